"""The wildfire-fighting environment of SPEC section 3 (ED and FS-dT), in two engines.

- :func:`make_env`: the fast numba engine (:class:`WildfireEnv`), a whole batch per policy call.
- :func:`make_reference_env`: the SimPy model (:class:`ReferenceEnv`), the oracle.

Both implement :class:`repro.core.rollout.BatchEnv` and agree decision by decision (tests).
"""

from __future__ import annotations

import argparse

from repro.core.errors import require
from repro.envs.wildfire.params import (EpisodeDraws, WildfireConfig, draw_episodes,
                                        fire_positions)

TRAIN_DEFAULTS = dict(lam=1.0, batch_episodes=600, epochs=300)
"""The paper's training settings: lambda 1, 600-1200 episodes per epoch, 300 epochs."""


def add_env_arguments(parser: argparse.ArgumentParser) -> None:
    """The simulator options: ED or FS-dT, T_health, the discount rate, the quirk switches, the
    decision limit."""
    parser.add_argument("--sim", choices=("ed", "fs"), default="ed",
                        help="event-driven, or fixed-step (needs --dt)")
    parser.add_argument("--dt", type=float, help="FS time step dT in seconds (only with --sim fs)")
    parser.add_argument("--t-health", type=float, default=WildfireConfig.t_health,
                        help="UAV-seconds to put out a fire (paper: 3.0; C9 uses 2.9999)")
    parser.add_argument("--gamma", type=float, default=WildfireConfig.gamma,
                        help="continuous-time discount rate per second (0.02); it also sets the "
                             "episode cap T_max = ln(0.005) / -gamma")
    parser.add_argument("--quirk-q1", action=argparse.BooleanOptionalAction,
                        default=WildfireConfig.quirk_q1_stale_attack,
                        help="Q1: a UAV that flew off does not rejoin the fire it attacked")
    parser.add_argument("--quirk-q2", action=argparse.BooleanOptionalAction,
                        default=WildfireConfig.quirk_q2_penalty_party_only,
                        help="Q2: the penalty goes to the extinguish party only")
    parser.add_argument("--max-decisions", type=int,
                        help="end an episode when a UAV's macro-action ends after this many of its "
                             "decisions (not in the paper; default and 0: no limit)")


def config_from_args(args: argparse.Namespace) -> WildfireConfig:
    """The validated config of the options of :func:`add_env_arguments` (UsageError if bad)."""
    if args.sim == "fs":
        require(args.dt is not None, "--dt", "given with --sim fs")
    else:
        require(args.dt is None, "--dt", "only used with --sim fs", args.dt)
    cfg = WildfireConfig(dt=args.dt, t_health=args.t_health, gamma=args.gamma,
                         quirk_q1_stale_attack=args.quirk_q1,
                         quirk_q2_penalty_party_only=args.quirk_q2,
                         max_decisions=args.max_decisions or None)  # 0: no limit
    cfg.validate()
    return cfg


def make_env(cfg: WildfireConfig):
    """The fast engine."""
    from repro.envs.wildfire.engine import WildfireEnv

    return WildfireEnv(cfg)


def make_reference_env(cfg: WildfireConfig):
    """The SimPy reference (same ``rollout`` signature, much slower)."""
    from repro.envs.wildfire.reference import ReferenceEnv

    return ReferenceEnv(cfg)


__all__ = ["WildfireConfig", "EpisodeDraws", "draw_episodes", "fire_positions",
           "add_env_arguments", "config_from_args", "make_env", "make_reference_env"]
