"""Real-time bus holding on a loop corridor (docs/semantics.md section 4; paper section "Real-Time
Bus Holding").

``make_env`` gives the fast numba engine, ``make_reference_env`` the SimPy reference it is tested
against; both implement :class:`repro.core.rollout.BatchEnv`.
"""

from __future__ import annotations

import argparse

import numpy as np

from repro.core.config import add_config_arguments, given_fields
from repro.envs.bus.engine import BusEnv
from repro.envs.bus.params import SWITCHES, BusConfig
from repro.envs.bus.reference import ReferenceBusEnv
from repro.envs.bus.vector import BusVectorEnv

TRAIN_DEFAULTS = dict(lam=2.0, batch_episodes=540, epochs=300)
"""Training settings of ``train --env bus``: the paper's lambda 2 and 540 episodes per epoch; the
paper gives no epoch count (the sweeps train 100 at paper scale, where the return is flat)."""


def add_env_arguments(parser: argparse.ArgumentParser,
                      fields: tuple[str, ...] | None = None) -> None:
    """A flag for every :class:`BusConfig` field (or those of ``fields``), and --corrected."""
    parser.add_argument("--corrected", action="store_true",
                        help="turn B1-B5 off (the paper's prose, docs/semantics.md section 4.9); "
                             "a switch given as well still sets that one")
    add_config_arguments(parser, BusConfig, fields)


def add_switch_arguments(parser: argparse.ArgumentParser) -> None:
    """The switches B1-B5 (default: the released simulator's behaviour) and --corrected."""
    add_env_arguments(parser, SWITCHES)


def config_from_args(args: argparse.Namespace) -> BusConfig:
    """The validated config of the options of :func:`add_env_arguments` or
    :func:`add_switch_arguments` (UsageError if bad)."""
    given = given_fields(args, BusConfig)
    if getattr(args, "corrected", False):
        return BusConfig.corrected(**given)
    return BusConfig(**given)


def make_env(cfg: BusConfig | None = None) -> BusEnv:
    return BusEnv(cfg)


def make_vector_env(n_envs: int, seed: int | np.random.SeedSequence = 0,
                    **config) -> BusVectorEnv:
    """The fast engine's step API (:mod:`repro.core.vector`) on ``n_envs`` episodes at a time
    (``seed`` unused: the environment is deterministic); ``config``: :class:`BusConfig` fields."""
    return BusVectorEnv(BusConfig(**config), n_envs, seed)


def make_reference_env(cfg: BusConfig | None = None) -> ReferenceBusEnv:
    return ReferenceBusEnv(cfg)


__all__ = ["BusConfig", "BusEnv", "ReferenceBusEnv", "add_env_arguments",
           "add_switch_arguments", "config_from_args",
           "make_env", "make_reference_env", "make_vector_env"]
