"""Event-driven multi-agent environments, and how ``--env`` finds one.

An environment is a module (a built-in package ``repro.envs.<name>``, or any importable module of
the user's) that provides the environment contract:

- ``add_env_arguments(parser)``: its command-line options;
- ``config_from_args(args) -> config``: its config (a dataclass) from the parsed options (for a
  config dataclass, :func:`repro.core.config.add_config_arguments` and
  :func:`~repro.core.config.given_fields` make both from its fields, as the built-in ones do);
- ``make_env(config) -> BatchEnv``: its fast engine (:class:`repro.core.rollout.BatchEnv`);
- optionally ``make_reference_env(config)``: a plain reference model the engine is tested
  against, ``make_vector_env(n_envs, seed, **config)``: the engine's step API
  (:class:`repro.core.vector.VectorEnv`, see :func:`make_vector_env`), and ``TRAIN_DEFAULTS``:
  training settings (``lam``, ``batch_episodes``, ``epochs``) that differ from
  :class:`repro.learn.config.TrainConfig`'s.
"""

from __future__ import annotations

import importlib
from types import ModuleType

import numpy as np

from repro.core.errors import UsageError, require
from repro.core.vector import VectorEnv

BUILT_IN = ("toy", "wildfire", "bus")
"""The suite's own environments, named by their package under ``repro.envs``."""
CONTRACT = ("add_env_arguments", "config_from_args", "make_env")
"""What a module must provide to be trained (see the module docstring)."""


def env_package(name: str) -> ModuleType:
    """The environment ``name``: a built-in one, or the importable module of that dotted name. A
    name that imports nothing, or a module without the contract, is a UsageError for ``--env``."""
    allowed = (f"one of {', '.join(BUILT_IN)}, or an importable module that provides "
               f"{', '.join(CONTRACT)}")
    module_name = f"repro.envs.{name}" if name in BUILT_IN else name
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as err:
        # only the module asked for (or a package above it) missing; a missing dependency of an
        # environment that exists is a real error
        if err.name is None or not module_name.startswith(err.name):
            raise
        raise UsageError("--env", allowed, name) from None
    except (ValueError, TypeError):  # an empty or relative name
        raise UsageError("--env", allowed, name) from None
    require(all(callable(getattr(module, f, None)) for f in CONTRACT), "--env", allowed, name)
    return module


def train_defaults(module: ModuleType) -> dict:
    """The environment's own training defaults (``TRAIN_DEFAULTS``; none if it has none)."""
    return dict(getattr(module, "TRAIN_DEFAULTS", {}))


def make_vector_env(name: str, n_envs: int, seed: int | np.random.SeedSequence = 0,
                    **config) -> VectorEnv:
    """The step API of environment ``name``'s fast engine: ``n_envs`` episodes of the stream of
    ``seed`` at a time (see :mod:`repro.core.vector`); ``config``: fields of its config."""
    module = env_package(name)
    require(callable(getattr(module, "make_vector_env", None)), "--env",
            "an environment with a step API (make_vector_env)", name)
    return module.make_vector_env(n_envs, seed, **config)
