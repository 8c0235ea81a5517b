"""Real-time bus holding on a loop corridor (SPEC section 5; paper section "Real-Time Bus Holding").

``make_env`` gives the fast numba engine, ``make_reference_env`` the SimPy reference it is tested
against; both implement :class:`repro.core.rollout.BatchEnv`.
"""

from __future__ import annotations

import argparse

from repro.envs.bus.engine import BusEnv
from repro.envs.bus.params import BusConfig
from repro.envs.bus.reference import ReferenceBusEnv

TRAIN_DEFAULTS = dict(lam=2.0, batch_episodes=540, epochs=300)
"""The paper's training settings: lambda 2, 540 episodes per epoch."""


def add_env_arguments(parser: argparse.ArgumentParser) -> None:
    """The bus environment's one command-line option, its discount rate; every other parameter is
    the paper's."""
    parser.add_argument("--gamma", type=float, default=BusConfig.gamma,
                        help="continuous-time discount rate per second (1e-5)")


def config_from_args(args: argparse.Namespace) -> BusConfig:
    """The validated config of the options of :func:`add_env_arguments` (UsageError if bad)."""
    return BusConfig(gamma=args.gamma)


def make_env(cfg: BusConfig | None = None) -> BusEnv:
    return BusEnv(cfg)


def make_reference_env(cfg: BusConfig | None = None) -> ReferenceBusEnv:
    return ReferenceBusEnv(cfg)


__all__ = ["BusConfig", "BusEnv", "ReferenceBusEnv", "add_env_arguments", "config_from_args",
           "make_env", "make_reference_env"]
