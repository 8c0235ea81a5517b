"""Scales: every driver's config has the same fields at every scale; a scale only changes sizes.

A driver config is a frozen dataclass with a class attribute ``SCALES`` mapping ``smoke``/``quick``/
``paper`` to field overrides (``quick`` is the default scale). ``for_scale`` builds the config for a
scale and applies any explicit overrides from the command line.
"""

from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

from repro.core.errors import UsageError

SCALES = ("smoke", "quick", "paper")
DEFAULT_SCALE = "quick"

C = TypeVar("C")


class Validated:
    """Base of the configs: a dataclass that has a ``validate`` method runs it on construction, so
    no config with a bad value exists (``dataclasses.replace`` validates too)."""

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Raise :class:`~repro.core.errors.UsageError` naming a bad field (subclasses)."""


def for_scale(cls: type[C], scale: str, **overrides: Any) -> C:
    """The config of ``cls`` at ``scale``; overrides whose value is ``None`` are ignored."""
    if scale not in SCALES:
        raise UsageError("--scale", "one of " + ", ".join(SCALES), scale)
    fields = dict(getattr(cls, "SCALES", {}).get(scale, {}))
    fields.update({k: v for k, v in overrides.items() if v is not None})
    return cls(**fields)  # type: ignore[call-arg]


def to_dict(cfg: Any) -> dict[str, Any]:
    """A JSON-ready dict of a (possibly nested) dataclass config."""
    return dataclasses.asdict(cfg)


def saved_defaults(config_type: type) -> dict[str, Any]:
    """What a run recorded before a setting existed held for it: its default, unless the config
    class names another value in ``BEFORE_ADDED`` (e.g. a switch whose default changed when it
    was added)."""
    return {**to_dict(config_type()), **getattr(config_type, "BEFORE_ADDED", {})}
