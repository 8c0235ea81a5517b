"""Configs: one frozen dataclass per set of settings, from which everything else follows.

A config's fields, with their docstrings, are its only definition: :func:`add_config_arguments`
makes a command-line flag of each (``--field-name``, its help the docstring's first sentence),
:func:`given_fields` reads them back, :meth:`Validated.check` names a bad field by its flag, and
:func:`numba_record` turns a config into the parameter record of a numba engine. A config class
may name older spellings of its fields in ``ALIASES`` (old name -> field): each is a further flag
of the field, and a key that saved configs and config files may still carry.

Scales: every driver's config has the same fields at every scale; a scale only changes sizes. A
driver config has a class attribute ``SCALES`` mapping ``smoke``/``quick``/``paper`` to field
overrides (``quick`` is the default scale); :func:`for_scale` builds the config for a scale and
applies any explicit overrides from the command line.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import functools
import inspect
import re
import textwrap
import types
import typing
from typing import Any, TypeVar

import numpy as np

from repro.core.errors import UsageError, require

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

    def check(self, condition: bool, field: str, allowed: str) -> None:
        """Refuse (UsageError) the value of ``field`` unless ``condition`` holds, naming the
        field's flag and its value."""
        value = getattr(self, field)
        require(condition, flag(field), allowed, list(value) if isinstance(value, tuple) else value)


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


def from_recorded(cls: type[C], values: dict[str, Any]) -> C:
    """The config ``cls`` that a sidecar records as ``values`` (:func:`to_dict`, through JSON):
    its fields, with JSON's lists as the tuples a config holds; other keys are ignored (a study
    built on the config records more beside its fields)."""
    fields = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    return cls(**{k: _as_tuples(v) for k, v in values.items() if k in fields})


def _as_tuples(value: Any) -> Any:
    return tuple(_as_tuples(v) for v in value) if isinstance(value, list) else value


def saved_defaults(config_type: type) -> dict[str, Any]:
    """What a run recorded before a setting existed held for it: its default, unless the config
    class names another value in ``BEFORE_ADDED`` (e.g. a switch whose default changed when it
    was added)."""
    return {**to_dict(config_type()), **getattr(config_type, "BEFORE_ADDED", {})}


# --- one definition per setting ------------------------------------------------------------------

def flag(field: str) -> str:
    """The command-line flag of a config field: ``max_decisions`` -> ``--max-decisions``."""
    return "--" + field.replace("_", "-")


@functools.cache
def field_docs(cls: type) -> dict[str, str]:
    """Each field's docstring (the string after its definition) in ``cls`` and its bases."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if not dataclasses.is_dataclass(klass):
            continue
        body = ast.parse(textwrap.dedent(inspect.getsource(klass))).body[0].body
        for node, after in zip(body, body[1:]):
            if (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)
                    and isinstance(after, ast.Expr) and isinstance(after.value, ast.Constant)
                    and isinstance(after.value.value, str)):
                docs[node.target.id] = inspect.cleandoc(after.value.value)
    return docs


def field_help(cls: type, field: str) -> str:
    """A field's help text: the first sentence of its docstring."""
    doc = " ".join(field_docs(cls).get(field, "").split())
    doc = re.sub(r":\w+:`~?([^`]*)`", r"\1", doc).replace("``", "")
    match = re.match(r"(.+?[.!?])(\s|$)", doc)
    return match.group(1) if match else doc


def settings(cls: type) -> list[str]:
    """The fields of ``cls`` that are settings (every dataclass field, in order)."""
    return [f.name for f in dataclasses.fields(cls)]


@functools.cache
def _type_hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _field_type(cls: type, field: str) -> tuple[type, bool, bool]:
    """(scalar type, optional: None allowed, sequence: a tuple of that type) of a field, from its
    annotation: ``int``, ``float | None``, ``tuple[int, ...]`` and so on."""
    hint = _type_hints(cls)[field]
    args = typing.get_args(hint)
    optional = isinstance(hint, types.UnionType) and type(None) in args
    if optional:
        hint = next(a for a in args if a is not type(None))
    sequence = typing.get_origin(hint) is tuple
    return (typing.get_args(hint)[0] if sequence else hint), optional, sequence


def _parse_value(kind: type, optional: bool):
    """argparse's ``type`` of one value of a field: the scalar type, and "none" for None."""
    def parse(text: str) -> Any:
        if optional and text.lower() == "none":
            return None
        try:
            return kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {parse.allowed}, got {text!r}") from None
    parse.__name__ = kind.__name__
    parse.optional = optional  # type: ignore[attr-defined]
    parse.allowed = _describe(kind, optional)  # type: ignore[attr-defined]
    return parse


def _describe(kind: type, optional: bool) -> str:
    words = {bool: "true or false", int: "an integer", float: "a number", str: "a word"}
    return words.get(kind, kind.__name__) + (" or none" if optional else "")


def add_config_arguments(parser: Any, cls: type, fields: tuple[str, ...] | None = None,
                         show_defaults: bool = True,
                         defaults: dict[str, Any] | None = None) -> None:
    """A flag for each field of ``cls`` (or of ``fields``), and one for each of its old spellings
    (``cls.ALIASES``): ``--field`` takes a value of the field's type ("none" where None is
    allowed), one or more for a tuple (``--sizes 1 2``, or ``--sizes 1 --sizes 2``); a boolean
    field is ``--field`` / ``--no-field``. A flag not given leaves no attribute
    (:func:`given_fields`). ``show_defaults``: the help ends with the field's default and the
    scales that change it (False where another layer, such as a named learner, sets it);
    ``defaults``: a command's own defaults of some fields, shown instead (the command applies
    them)."""
    old = {}
    for alias, name in getattr(cls, "ALIASES", {}).items():
        old.setdefault(name, []).append(flag(alias))
    own = defaults or {}
    declared = {f.name: f.default for f in dataclasses.fields(cls)}
    for name in fields or settings(cls):
        kind, optional, sequence = _field_type(cls, name)
        text = field_help(cls, name)
        if name in own:
            text += f" (default here: {_shown(own[name])})"
        elif show_defaults and declared[name] is not dataclasses.MISSING:
            text += f" (default: {_default_text(cls, name, declared[name])})"
        if old.get(name):
            text += f" (old spelling: {', '.join(old[name])})"
        names = (flag(name), *old.get(name, ()))
        text = text.replace("%", "%%")  # argparse formats help with %
        if kind is bool and not sequence:
            action = parser.add_argument(*names, dest=name, default=argparse.SUPPRESS, help=text,
                                         action=argparse.BooleanOptionalAction)
        elif sequence:  # --sizes 1 2, or --sizes 1 --sizes 2
            action = parser.add_argument(*names, dest=name, type=_parse_value(kind, optional),
                                         action="extend", nargs="+", default=argparse.SUPPRESS,
                                         help=text)
        else:
            action = parser.add_argument(*names, dest=name, type=_parse_value(kind, optional),
                                         default=argparse.SUPPRESS, help=text)
        action.setting = (cls, name)  # whose value a scale sets (scale_departures)
        if name in own:
            action.own_default = own[name]  # this command's value instead of any scale's


def _shown(value: Any) -> str:
    """A value as help shows it (a tuple's items separated by spaces, as the flag takes them)."""
    if isinstance(value, tuple):
        return " ".join(map(str, value)) if value else "none"
    return str(value)


def _default_text(cls: type, name: str, default: Any) -> str:
    """A field's default as help shows it, with the scales that change it (``cls.SCALES``)."""
    scaled = [f"{scale}: {_shown(fields[name])}" for scale, fields in
              getattr(cls, "SCALES", {}).items() if name in fields]
    return "; ".join([_shown(default), *scaled])


def given_fields(args: argparse.Namespace, cls: type,
                 fields: tuple[str, ...] | None = None) -> dict[str, Any]:
    """The fields of ``cls`` (or of ``fields``) that flags of :func:`add_config_arguments` gave
    (tuples as tuples)."""
    given = {}
    for name in fields or settings(cls):
        if hasattr(args, name):
            value = getattr(args, name)
            given[name] = tuple(value) if isinstance(value, list) else value
    return given


def canonical_keys(cls: type, values: dict[str, Any]) -> dict[str, Any]:
    """``values`` with the old spellings of ``cls``'s fields (``cls.ALIASES``) renamed."""
    aliases = getattr(cls, "ALIASES", {})
    return {aliases.get(k, k): v for k, v in values.items()}


# --- the record a numba engine reads its parameters from -----------------------------------------

def numba_record(cfg: Any, **extra: Any) -> np.ndarray:
    """The (1,) aligned structured array of a numba engine's parameters: every number and switch
    of ``cfg`` under its field name (None as 0; a tuple as a float array), then ``extra``
    (name -> a bool, int, float or array: what the engine derives from the config). String
    fields are left out: an engine reads what it derives from them, by a name of its own."""
    entries: dict[str, Any] = {}
    for name in settings(type(cfg)):
        kind, _, sequence = _field_type(type(cfg), name)
        value = getattr(cfg, name)
        if kind is not str:
            entries[name] = (np.asarray(value, np.float64) if sequence
                             else kind(0) if value is None else value)
    entries.update(extra)
    dtype = np.dtype([_record_field(k, v) for k, v in entries.items()], align=True)
    record = np.zeros(1, dtype)
    record[0] = tuple(entries.values())
    return record


def _record_field(name: str, value: Any) -> tuple:
    if isinstance(value, np.ndarray):
        return (name, value.dtype, value.shape)
    if isinstance(value, (bool, np.bool_)):
        return (name, np.bool_)
    return (name, np.int64 if isinstance(value, (int, np.integer)) else np.float64)


# --- config files --------------------------------------------------------------------------------

CONFIG_SECTIONS = ("train", "env")
"""Sections of a run's config.json (and of a hand-written file like it): their keys are read as
if at the top level. The run's ``env_name`` is its ``train.env``."""


def read_config_file(path: str, param: str = "--config") -> dict[str, Any]:
    """The table of a JSON or TOML file (``.toml``; any other name is read as JSON). UsageError
    naming ``param`` if the file cannot be read or parsed, or holds no table."""
    import json
    import tomllib

    try:
        with open(path, "rb") as f:
            data = tomllib.load(f) if str(path).endswith(".toml") else json.load(f)
    except (OSError, ValueError) as err:  # JSON's and TOML's decode errors are ValueErrors
        reason = getattr(err, "strerror", None) or str(err).splitlines()[0]
        raise UsageError(param, f"a readable JSON or TOML file of settings ({reason})",
                         str(path)) from None
    require(isinstance(data, dict), param, "a JSON object or TOML table of settings", str(path))
    return data


def flat_settings(data: dict[str, Any], path: str) -> dict[str, Any]:
    """The settings of a config file's table: setting -> value, the keys of the sections
    ``CONFIG_SECTIONS`` (a run's config.json) read as if at the top level. UsageError naming the
    key if the file gives a setting twice, with different values."""
    flat: dict[str, Any] = {}
    for key, value in data.items():
        if key == "env_name" and isinstance(value, str):
            key = "env"
        items = value.items() if key in CONFIG_SECTIONS and isinstance(value, dict) else [
            (key, value)]
        for name, item in items:
            require(name not in flat or flat[name] == item, f"{path}: {name}",
                    "given once (the file gives it twice, with different values)", item)
            flat[name] = item
    return flat
