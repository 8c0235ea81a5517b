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
from dataclasses import replace
from typing import Callable

import numpy as np

from repro.core.errors import require
from repro.core.rollout import Policy, Rollout, concat, rollout_bytes
from repro.envs.wildfire import (QUIRKS, add_env_arguments, config_from_args, make_env,
                                 make_reference_env)
from repro.envs.wildfire.policies import POLICIES
from repro.runs.memory import require_memory
from repro.runs.stats import sem

BATCH_EPISODES = 1000
"""Episodes per engine call (bounds memory; the fast engine's throughput is flat beyond this)."""
ENGINES = ("fast", "reference")


def adr(rollout: Rollout, gamma: float) -> tuple[float, float]:
    """Average discounted return over all paths, and its standard error."""
    r = rollout.discounted_path_returns(gamma)
    return float(np.mean(r)), sem(r)


def evaluate(env, policy: Policy, n_episodes: int, seed: int, keep_obs: bool = True,
             on_batch: Callable[[Rollout], object] | None = None,
             param: str = "--test-episodes") -> Rollout:
    """Roll out ``n_episodes`` in batches seeded from children of ``seed``. ``keep_obs=False`` drops
    each batch's observations and engine log (``info``) as soon as it is done (the result's ``obs``
    has 0 columns): ADR does not need them, and a learned policy that keeps flying to the fire it is
    at can take tens of millions of decisions over 10,000 test episodes; with their observations,
    one paper-scale transfer test filled the machine's 24 GB. ``on_batch`` sees each whole batch
    first. A number of episodes whose rollouts cannot fit in memory is refused first
    (UsageError naming ``param``)."""
    require_memory(rollout_bytes(env, n_episodes, keep_obs=keep_obs, batch=BATCH_EPISODES),
                   param, n_episodes, "the rollouts")
    n_batches = -(-n_episodes // BATCH_EPISODES)
    children = np.random.SeedSequence(seed).spawn(n_batches)
    sizes = [min(BATCH_EPISODES, n_episodes - c * BATCH_EPISODES) for c in range(n_batches)]
    batches = []
    for n, ss in zip(sizes, children):
        batch = env.rollout(policy, n, ss)
        if on_batch is not None:
            on_batch(batch)
        batches.append(batch if keep_obs else replace(batch, obs=batch.obs[:, :0], info={}))
    return concat(batches)


def _cut(n_truncated: int) -> str:
    return f"; {n_truncated} ended at the decision limit" if n_truncated else ""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--policy", choices=tuple(POLICIES), required=True, help="heuristic policy")
    p.add_argument("--engine", choices=ENGINES, default="fast", help="fast (numba) or SimPy")
    add_env_arguments(p)
    p.add_argument("--episodes", type=int, default=1000, help="test episodes")
    p.add_argument("--seed", type=int, default=0, help="root seed (environment and policy)")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    cfg = config_from_args(args)
    require(args.episodes >= 1, "--episodes", "an integer >= 1", args.episodes)
    env = (make_env if args.engine == "fast" else make_reference_env)(cfg)
    env_seed, policy_seed = np.random.SeedSequence(args.seed).spawn(2)
    policy = POLICIES[args.policy](np.random.default_rng(policy_seed),
                                   n_observed=cfg.n_observed)
    t0 = time.perf_counter()
    rollout = evaluate(env, policy, args.episodes, int(env_seed.generate_state(1)[0]),
                       param="--episodes")
    seconds = time.perf_counter() - t0
    mean, err = adr(rollout, cfg.gamma)
    out = dict(adr=mean, sem=err, episodes=args.episodes, decisions=rollout.n_decisions,
               seconds=round(seconds, 3), decisions_per_second=rollout.n_decisions / seconds,
               mean_episode_return=float(rollout.episode_return.mean()), policy=args.policy,
               engine=args.engine, sim=cfg.label, t_health=cfg.t_health,
               **{f: getattr(cfg, f) for f in QUIRKS},
               same_instant_order=cfg.same_instant_order,
               max_decisions=cfg.max_decisions or 0, truncated_episodes=rollout.n_truncated,
               seed=args.seed)
    if args.json:
        print(json.dumps(out, sort_keys=True))
    else:
        print(f"{args.policy} on {cfg.label} (T_health={cfg.t_health:g}, {args.engine}): "
              f"ADR {mean:.4f} +- {err:.4f} over {args.episodes} episodes "
              f"({rollout.n_decisions} decisions, {seconds:.2f} s"
              f"{_cut(rollout.n_truncated)})")
    return 0
