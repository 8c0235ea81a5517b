"""The wildfire-fighting environment of docs/semantics.md section 3 (ED and FS-dT), in two engines.

- :func:`make_env`: the fast numba engine (:class:`WildfireEnv`), a whole batch per policy call.
- :func:`make_reference_env`: the SimPy model (:class:`ReferenceEnv`), the oracle.

Both implement :class:`repro.core.rollout.BatchEnv` and agree decision by decision (tests).
"""

from __future__ import annotations

import argparse

import numpy as np

from repro.core.errors import require
from repro.envs.wildfire.params import (FIGURE_VERSION, QUIRKS, RELEASED_VERSION, SIM_VERSIONS,
                                        EpisodeDraws, WildfireConfig, draw_episodes,
                                        fire_positions, version_suffix)

TRAIN_DEFAULTS = dict(lam=1.0, batch_episodes=600, epochs=300)
"""The paper's training settings: lambda 1, 600-1200 episodes per epoch, 300 epochs."""


def add_env_arguments(parser: argparse.ArgumentParser) -> None:
    """The simulator options: ED or FS-dT, T_health, the discount rate, the quirk switches, the
    same-instant and ranking rules, the decision limit."""
    parser.add_argument("--sim", choices=("ed", "fs"), default="ed",
                        help="event-driven, or fixed-step (needs --dt)")
    parser.add_argument("--dt", type=float, help="FS time step dT in seconds (only with --sim fs)")
    parser.add_argument("--t-health", type=float, default=WildfireConfig.t_health,
                        help="UAV-seconds to put out a fire (paper: 3.0; C9 uses 2.9999)")
    parser.add_argument("--r-pen", type=float, default=WildfireConfig.r_pen,
                        help="crowding penalty (%(default)s: the released HEAD of 2017-05-16; -1: "
                             "the simulator of 2017-04-22 the transfer runs were trained on)")
    parser.add_argument("--gamma", type=float, default=WildfireConfig.gamma,
                        help="continuous-time discount rate per second (0.02); it also sets the "
                             "episode cap T_max = ln(0.005) / -gamma")
    parser.add_argument("--quirk-q1", action=argparse.BooleanOptionalAction,
                        default=WildfireConfig.quirk_q1_stale_attack,
                        help="Q1: a UAV that flew off does not rejoin the fire it attacked")
    parser.add_argument("--quirk-q2", action=argparse.BooleanOptionalAction,
                        default=WildfireConfig.quirk_q2_penalty_party_only,
                        help="Q2: the penalty goes to the extinguish party only")
    for q, help_ in (("q3", "observed health unclamped, out fires keep draining"),
                     ("q4", "a fire out during a UAV's decision latency does not interrupt it"),
                     ("q5", "rewards discounted from the action's start, not the observation"),
                     ("q6", "a flight shorter than 1e-3 m leaves the UAV where it was")):
        field = next(f for f in QUIRKS if f.startswith(f"quirk_{q}_"))
        parser.add_argument(f"--quirk-{q}", action=argparse.BooleanOptionalAction,
                            default=getattr(WildfireConfig, field), help=f"{q.upper()}: {help_}")
    parser.add_argument("--same-instant-order", default=WildfireConfig.same_instant_order,
                        help="order of events at one instant: released (the released code's "
                             "process structure) or scheduling (each process waits on its own "
                             "timeouts; the episode ends at once)")
    parser.add_argument("--fire-out-first", action=argparse.BooleanOptionalAction,
                        default=WildfireConfig.fire_out_first,
                        help="at one instant a fire goes out before a UAV whose macro-action "
                             "ends then observes (released); --no-fire-out-first: the UAV first")
    parser.add_argument("--fs-round-negative-delays", action=argparse.BooleanOptionalAction,
                        default=WildfireConfig.fs_round_negative_delays,
                        help="FS: a fire re-planned after its health ran out is rounded like any "
                             "delay (released), not first clamped to 0")
    parser.add_argument("--cut-flight-continues", action=argparse.BooleanOptionalAction,
                        default=WildfireConfig.cut_flight_continues,
                        help="a cut flight goes on until the UAV's next action starts (released)")
    parser.add_argument("--ranking-resolution", type=float,
                        default=WildfireConfig.ranking_resolution,
                        help="fires are ranked by distance rounded to this (m), ties to the "
                             "lower index; 0: exact distances")
    parser.add_argument("--max-decisions", type=int, default=WildfireConfig.max_decisions,
                        help="end an episode (reported truncated) when a UAV's macro-action ends "
                             "after this many of its decisions (not in the paper; default "
                             "%(default)s; 0: no limit, as the released simulator)")


def config_from_args(args: argparse.Namespace) -> WildfireConfig:
    """The validated config of the options of :func:`add_env_arguments` (UsageError if bad)."""
    if args.sim == "fs":
        require(args.dt is not None, "--dt", "given with --sim fs")
    else:
        require(args.dt is None, "--dt", "only used with --sim fs", args.dt)
    quirks = {f: getattr(args, f"quirk_{f.split('_')[1]}") for f in QUIRKS}
    cfg = WildfireConfig(dt=args.dt, t_health=args.t_health, gamma=args.gamma, r_pen=args.r_pen,
                         **quirks,
                         same_instant_order=args.same_instant_order,
                         fire_out_first=args.fire_out_first,
                         fs_round_negative_delays=args.fs_round_negative_delays,
                         cut_flight_continues=args.cut_flight_continues,
                         ranking_resolution=args.ranking_resolution,
                         max_decisions=args.max_decisions or None)  # 0: no limit
    return cfg


def make_env(cfg: WildfireConfig, count_races: bool = False):
    """The fast engine; ``count_races``: each episode's races (docs/semantics.md section 3.12) in
    its rollouts' ``info["races"]``."""
    from repro.envs.wildfire.engine import WildfireEnv

    return WildfireEnv(cfg, count_races)


def make_vector_env(n_envs: int, seed: int | np.random.SeedSequence, **config):
    """The fast engine's step API (:mod:`repro.core.vector`) on ``n_envs`` episodes at a time of
    the stream of ``seed``; ``config``: :class:`WildfireConfig` fields."""
    from repro.envs.wildfire.vector import WildfireVectorEnv

    return WildfireVectorEnv(WildfireConfig(**config), n_envs, seed)


def make_reference_env(cfg: WildfireConfig, count_races: bool = False):
    """The SimPy reference (same ``rollout`` signature, much slower)."""
    from repro.envs.wildfire.reference import ReferenceEnv

    return ReferenceEnv(cfg, count_races)


__all__ = ["WildfireConfig", "QUIRKS", "SIM_VERSIONS", "RELEASED_VERSION", "FIGURE_VERSION",
           "version_suffix", "EpisodeDraws", "draw_episodes",
           "fire_positions",
           "add_env_arguments", "config_from_args", "make_env", "make_reference_env",
           "make_vector_env"]
