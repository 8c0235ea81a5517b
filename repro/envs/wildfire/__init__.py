"""The wildfire-fighting environment of docs/semantics.md section 3 (ED and FS-dT), in two engines.

- :func:`make_env`: the fast numba engine (:class:`WildfireEnv`), a whole batch per policy call.
- :func:`make_reference_env`: the SimPy model (:class:`ReferenceEnv`), the oracle.

Both implement :class:`repro.core.rollout.BatchEnv` and agree decision by decision (tests).
"""

from __future__ import annotations

import argparse

import numpy as np

from repro.core.config import add_config_arguments, given_fields
from repro.core.errors import require
from repro.envs.wildfire.params import (FIGURE_VERSION, QUIRKS, RELEASED_VERSION, SIM_VERSIONS,
                                        EpisodeDraws, WildfireConfig, draw_episodes,
                                        fire_positions, version_suffix)

TRAIN_DEFAULTS = dict(lam=1.0, batch_episodes=600, epochs=300)
"""The paper's training settings: lambda 1, 600-1200 episodes per epoch, 300 epochs."""


def add_env_arguments(parser: argparse.ArgumentParser) -> None:
    """A flag for every :class:`WildfireConfig` field (``--dt`` alone selects FS-dT;
    ``--max-decisions 0``: no limit), and ``--sim``, which names the simulator ``--dt`` selects."""
    parser.add_argument("--sim", choices=("ed", "fs"),
                        help="event-driven, or fixed-step (needs --dt); optional, --dt alone "
                             "selects FS")
    add_config_arguments(parser, WildfireConfig)


def config_from_args(args: argparse.Namespace) -> WildfireConfig:
    """The validated config of the options of :func:`add_env_arguments` (UsageError if bad)."""
    given = given_fields(args, WildfireConfig)
    if getattr(args, "sim", None) == "fs":
        require(given.get("dt") is not None, "--dt", "given with --sim fs")
    elif getattr(args, "sim", None) == "ed":
        require(given.get("dt") is None, "--dt", "only used with --sim fs", given.get("dt"))
    if "max_decisions" in given:
        given["max_decisions"] = given["max_decisions"] or None  # 0: no limit
    return WildfireConfig(**given)


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
