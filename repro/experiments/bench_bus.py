"""Speed of the fast bus engine against its SimPy reference, with the learner's policy in the loop.

Both engines run the same policies: No Holding, and a 2x32 tanh MLP (random weights) evaluated the
way the learner's sampler does it, one batched forward per round in numpy plus inverse-CDF sampling,
so episodes desynchronise as in training. The fast engine runs the training batch (540 episodes);
the reference runs fewer, as its cost per episode does not depend on the batch. Rates are per second
of this process's CPU time (the machine may be shared), with wall-clock seconds alongside; the fast
engine's JIT compilation is excluded by a warm-up rollout.

The policy's own time is the same per decision for both engines, so with the MLP it bounds the
speed-up: ``speedup_vs_simpy`` compares whole rollouts, ``engine_speedup_vs_simpy`` the time outside
the policy calls (``policy_cpu_seconds``), i.e. what the engine itself costs.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd

from repro.cli import add_common
from repro.core.config import for_scale
from repro.core.errors import require
from repro.core.io import check_writable_dir, provenance, write_result
from repro.core.rollout import BatchEnv, DecisionBatch, Policy
from repro.envs.bus import make_env, make_reference_env
from repro.envs.bus.engine import OBS_DIM
from repro.envs.bus.policies import no_holding


@dataclass(frozen=True)
class BenchConfig:
    """Batch sizes of the benchmark."""

    fast_episodes: int = 540
    """Episodes in one batch of the fast engine (540 = the paper's training batch)."""
    fast_repeats: int = 3
    """Batches the fast engine runs per policy (their times add up)."""
    reference_episodes: int = 20
    """Episodes in the SimPy reference's batch."""
    hidden: int = 32
    """Width of each of the MLP's two tanh hidden layers (the learner's)."""

    SCALES: ClassVar[dict] = {
        "smoke": dict(fast_episodes=54, fast_repeats=1, reference_episodes=2),
        "quick": {},
        "paper": dict(fast_repeats=10, reference_episodes=100),
    }


class MlpPolicy:
    """pi(a | o) = softmax(MLP(o)), two tanh hidden layers, sampled by inverse CDF with one uniform
    per row. The same computation as the learner's sampler (``repro.learn``): a numpy forward per
    batch, as a torch call per round would cost more than the engine's round itself."""

    def __init__(self, n_actions: int, hidden: int, rng: np.random.Generator):
        sizes = [OBS_DIM, hidden, hidden, n_actions]
        self.layers = [(rng.normal(0.0, 1.0 / np.sqrt(a), (a, b)), np.zeros(b))
                       for a, b in zip(sizes[:-1], sizes[1:])]
        self.scale = np.array([0.1, 0.1, 0.02, 0.001])  # stop, h (min), load, sojourn (s) -> O(1)
        self.rng = rng

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        x = batch.obs * self.scale
        for w, b in self.layers[:-1]:
            x = np.tanh(x @ w + b)
        w, b = self.layers[-1]
        logits = x @ w + b
        p = np.exp(logits - logits.max(axis=1, keepdims=True))
        cdf = np.cumsum(p, axis=1)
        u = self.rng.random(len(cdf)) * cdf[:, -1]
        return np.minimum((cdf <= u[:, None]).sum(axis=1), cdf.shape[1] - 1)


class _Counted:
    """A policy that counts the decisions it answers and the CPU time it takes."""

    def __init__(self, policy: Policy):
        self.policy = policy
        self.decisions = 0
        self.cpu = 0.0

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        self.decisions += len(batch)
        t0 = time.process_time()
        actions = self.policy(batch)
        self.cpu += time.process_time() - t0
        return actions


def _time(env: BatchEnv, policy: Policy, episodes: int, repeats: int) -> dict:
    counted = _Counted(policy)
    cpu, wall = time.process_time(), time.perf_counter()
    for _ in range(repeats):
        env.rollout(counted, episodes)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    n = episodes * repeats
    return dict(episodes=n, batch=episodes, decisions=counted.decisions, cpu_seconds=cpu,
                wall_seconds=wall, policy_cpu_seconds=counted.cpu, episodes_per_s=n / cpu,
                decisions_per_s=counted.decisions / cpu,
                engine_episodes_per_s=n / (cpu - counted.cpu))


def measure(cfg: BenchConfig, seed: int) -> pd.DataFrame:
    fast, ref = make_env(), make_reference_env()
    fast.rollout(no_holding, 1)  # compile
    rows = []
    for name in ("nohold", "mlp"):
        for engine, env, episodes, repeats in (("fast", fast, cfg.fast_episodes, cfg.fast_repeats),
                                               ("simpy", ref, cfg.reference_episodes, 1)):
            # each engine gets the same freshly seeded policy
            policy = (no_holding if name == "nohold" else
                      MlpPolicy(fast.n_actions, cfg.hidden, np.random.default_rng(seed)))
            rows.append(dict(policy=name, engine=engine, **_time(env, policy, episodes, repeats)))
    df = pd.DataFrame(rows)
    simpy = df[df.engine == "simpy"].set_index("policy")
    df["speedup_vs_simpy"] = df.episodes_per_s / df.policy.map(simpy.episodes_per_s)
    df["engine_speedup_vs_simpy"] = (df.engine_episodes_per_s
                                     / df.policy.map(simpy.engine_episodes_per_s))
    return df


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p)
    p.add_argument("--fast-episodes", type=int, help="episodes per batch of the fast engine")
    p.add_argument("--fast-repeats", type=int, help="batches the fast engine runs per policy")
    p.add_argument("--reference-episodes", type=int, help="episodes for the SimPy reference")


def run(args: argparse.Namespace) -> int:
    cfg = for_scale(BenchConfig, args.scale, fast_episodes=args.fast_episodes,
                    fast_repeats=args.fast_repeats, reference_episodes=args.reference_episodes)
    require(cfg.fast_episodes >= 1, "--fast-episodes", "an integer >= 1", cfg.fast_episodes)
    require(cfg.fast_repeats >= 1, "--fast-repeats", "an integer >= 1", cfg.fast_repeats)
    require(cfg.reference_episodes >= 1, "--reference-episodes", "an integer >= 1",
            cfg.reference_episodes)
    results = check_writable_dir(args.results_dir, "--results-dir")
    t0 = time.perf_counter()
    df = measure(cfg, args.seed)
    prov = provenance(cfg, command="bench-bus", scale=args.scale, seed=args.seed,
                      wall_seconds=time.perf_counter() - t0)
    write_result(results / "bench_bus.csv", df, prov)
    print(df.to_string(index=False))
    return 0
