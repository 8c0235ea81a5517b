"""Real-time bus holding on a loop corridor (docs/semantics.md section 4; paper section "Real-Time
Bus Holding").

``make_env`` gives the fast numba engine, ``make_reference_env`` the SimPy reference it is tested
against; both implement :class:`repro.core.rollout.BatchEnv`.
"""

from __future__ import annotations

import argparse

import numpy as np

from repro.envs.bus.engine import BusEnv
from repro.envs.bus.params import BusConfig
from repro.envs.bus.reference import ReferenceBusEnv
from repro.envs.bus.vector import BusVectorEnv

TRAIN_DEFAULTS = dict(lam=2.0, batch_episodes=540, epochs=300)
"""Training settings of ``train --env bus``: the paper's lambda 2 and 540 episodes per epoch; the
paper gives no epoch count (the sweeps train 100 at paper scale, where the return is flat)."""


SWITCH_FLAGS = {
    "b1_reward": ("--b1", "B1: the released reward (pax/s, seconds; none for h <= 0 or at a bus's "
                  "first two stop visits)"),
    "b2_headway": ("--b2", "B2: the released headway (to the bus ahead; -1 if unknown; seconds)"),
    "b3_boarding": ("--b3", "B3: the released boarding (the current time as headway at a bus's "
                    "first two stop visits)"),
    "b4_round_half_even": ("--b4", "B4: round U and B half to even"),
    "b5_timing": ("--b5", "B5: the released decision timing (the action starts 1e-5 s after the "
                  "observation)"),
}
"""BusConfig switch -> (command-line flag, help). Each flag has a --no- form."""


def add_switch_arguments(parser: argparse.ArgumentParser) -> None:
    """The switches B1-B5 (default: the released simulator's behaviour) and --corrected."""
    parser.add_argument("--corrected", action="store_true",
                        help="turn B1-B5 off (the paper's prose, docs/semantics.md section 4.9); "
                             "a --b<i> given as well still sets that one")
    for name, (flag, text) in SWITCH_FLAGS.items():
        parser.add_argument(flag, dest=name, action=argparse.BooleanOptionalAction, default=None,
                            help=text + " (default: on; off with --corrected)")


def switches_from_args(args: argparse.Namespace) -> dict[str, bool]:
    """The BusConfig switch fields chosen by the options of :func:`add_switch_arguments`."""
    return {name: (not args.corrected) if getattr(args, name) is None else getattr(args, name)
            for name in SWITCH_FLAGS}


def add_env_arguments(parser: argparse.ArgumentParser) -> None:
    """The bus environment's options: its discount rate and the switches B1-B5; every other
    parameter is the paper's."""
    parser.add_argument("--gamma", type=float, default=BusConfig.gamma,
                        help="continuous-time discount rate per second (1e-5)")
    add_switch_arguments(parser)


def config_from_args(args: argparse.Namespace) -> BusConfig:
    """The validated config of the options of :func:`add_env_arguments` or
    :func:`add_switch_arguments` (UsageError if bad)."""
    return BusConfig(gamma=getattr(args, "gamma", BusConfig.gamma), **switches_from_args(args))


def make_env(cfg: BusConfig | None = None) -> BusEnv:
    return BusEnv(cfg)


def make_vector_env(n_envs: int, seed: int | np.random.SeedSequence = 0,
                    **config) -> BusVectorEnv:
    """The fast engine's step API (:mod:`repro.core.vector`) on ``n_envs`` episodes at a time
    (``seed`` unused: the environment is deterministic); ``config``: :class:`BusConfig` fields."""
    return BusVectorEnv(BusConfig(**config), n_envs, seed)


def make_reference_env(cfg: BusConfig | None = None) -> ReferenceBusEnv:
    return ReferenceBusEnv(cfg)


__all__ = ["BusConfig", "BusEnv", "ReferenceBusEnv", "SWITCH_FLAGS", "add_env_arguments",
           "add_switch_arguments", "config_from_args", "switches_from_args",
           "make_env", "make_reference_env", "make_vector_env"]
