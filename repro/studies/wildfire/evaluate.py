"""Evaluate a heuristic policy on the wildfire environment: average discounted return (ADR).

ADR (docs/semantics.md section 6.1) is the mean, over every agent path of every test episode, of the
path's return discounted in continuous time (``Rollout.discounted_path_returns(gamma)``); its
standard error is taken over those paths. Episodes run in batches of ``BATCH_EPISODES``, batch c
drawing from child c of the root seed, so results depend on the seed only (and on the engine for
random policies: the reference asks the policy once per decision, the fast engine once per round).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass

import numpy as np

from repro.core.errors import require
from repro.envs.wildfire import (QUIRKS, WildfireConfig, add_env_arguments, config_from_args,
                                 make_env, make_reference_env)
from repro.envs.wildfire.policies import POLICIES
from repro.studies.wildfire.study import adr, evaluate

ENGINES = ("fast", "reference")


def _cut(n_truncated: int) -> str:
    return f"; {n_truncated} ended at the decision limit" if n_truncated else ""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--policy", choices=tuple(POLICIES), required=True, help="heuristic policy")
    p.add_argument("--engine", choices=ENGINES, default="fast", help="fast (numba) or SimPy")
    add_env_arguments(p)
    p.add_argument("--episodes", type=int, default=1000, help="test episodes")
    p.add_argument("--seed", type=int, default=0, help="root seed (environment and policy)")
    p.add_argument("--json", action="store_true", help="print one JSON object")


@dataclass(frozen=True)
class EvalConfig:
    """What ``wildfire-eval`` evaluates, and how it prints it."""

    policy: str
    """The heuristic policy (``--policy``)."""
    engine: str
    """The engine: fast (numba) or reference (SimPy) (``--engine``)."""
    episodes: int
    """Test episodes (``--episodes``)."""
    seed: int
    """The root seed of the environment and the policy (``--seed``)."""
    json: bool
    """Print one JSON object (``--json``)."""
    env: WildfireConfig
    """The simulator, as its options give it."""


def configure(args: argparse.Namespace) -> EvalConfig:
    cfg = config_from_args(args)
    require(args.episodes >= 1, "--episodes", "an integer >= 1", args.episodes)
    return EvalConfig(policy=args.policy, engine=args.engine, episodes=args.episodes,
                      seed=args.seed, json=args.json, env=cfg)


def run(cfg: EvalConfig) -> int:
    sim = cfg.env
    env = (make_env if cfg.engine == "fast" else make_reference_env)(sim)
    env_seed, policy_seed = np.random.SeedSequence(cfg.seed).spawn(2)
    policy = POLICIES[cfg.policy](np.random.default_rng(policy_seed),
                                  n_observed=sim.n_observed)
    t0 = time.perf_counter()
    rollout = evaluate(env, policy, cfg.episodes, int(env_seed.generate_state(1)[0]),
                       param="--episodes")
    seconds = time.perf_counter() - t0
    mean, err = adr(rollout, sim.gamma)
    out = dict(adr=mean, sem=err, episodes=cfg.episodes, decisions=rollout.n_decisions,
               seconds=round(seconds, 3), decisions_per_second=rollout.n_decisions / seconds,
               mean_episode_return=float(rollout.episode_return.mean()), policy=cfg.policy,
               engine=cfg.engine, sim=sim.label, t_health=sim.t_health,
               **{f: getattr(sim, f) for f in QUIRKS},
               same_instant_order=sim.same_instant_order,
               max_decisions=sim.max_decisions or 0, truncated_episodes=rollout.n_truncated,
               seed=cfg.seed)
    if cfg.json:
        print(json.dumps(out, sort_keys=True))
    else:
        print(f"{cfg.policy} on {sim.label} (T_health={sim.t_health:g}, {cfg.engine}): "
              f"ADR {mean:.4f} +- {err:.4f} over {cfg.episodes} episodes "
              f"({rollout.n_decisions} decisions, {seconds:.2f} s"
              f"{_cut(rollout.n_truncated)})")
    return 0
