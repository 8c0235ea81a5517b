"""Throughput of the two wildfire engines: with an MLP policy in the loop, and alone.

One process, one thread. Each engine simulates ED episodes (the fast one in batches of
``wildfire_eval.BATCH_EPISODES``, the training batch size) under two policies:

- ``mlp``: a 2x32 tanh MLP (float32 torch, one thread) sampling its categorical action by
  inverse CDF, one policy call per round of the whole batch;
- ``scripted``: actions looked up in a table drawn in advance (the engine alone, nearly free).

Throughput counts recorded decisions (and episodes) over wall time, the policy included; the same
over the process's CPU time too, which is what one core achieves when the machine is shared. The
fast engine is compiled (or loaded from cache) before timing. The speed-up compares the engines
under the same policy.
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd

from repro.cli import add_common
from repro.core.config import for_scale
from repro.core.errors import require
from repro.core.io import check_writable_dir, provenance, write_result
from repro.core.rollout import DecisionBatch
from repro.envs.wildfire import WildfireConfig, make_env, make_reference_env
from repro.experiments.wildfire_eval import BATCH_EPISODES, evaluate


@dataclass(frozen=True)
class BenchWildfireConfig:
    """Sizes of the benchmark (the timings are the result; the scale only changes the sizes)."""

    fast_episodes: int = 4000
    """Episodes simulated by the fast engine per policy (in batches of BATCH_EPISODES)."""
    reference_episodes: int = 30
    """Episodes simulated by the SimPy reference per policy."""
    hidden: int = 32
    """Units in each of the MLP's two tanh hidden layers."""

    SCALES: ClassVar[dict] = {
        "smoke": dict(fast_episodes=200, reference_episodes=2),
        "quick": {},
        "paper": dict(fast_episodes=20000, reference_episodes=100),
    }

    def validate(self) -> None:
        require(self.fast_episodes >= 1, "--fast-episodes", "an integer >= 1", self.fast_episodes)
        require(self.reference_episodes >= 1, "--reference-episodes", "an integer >= 1",
                self.reference_episodes)


class MLPPolicy:
    """obs -> tanh(hidden) -> tanh(hidden) -> softmax, a float32 torch network (as the learner's)
    on one thread; one uniform per row picks the action from the CDF. (numpy's matmul would hand
    batches of about 1000 rows to several BLAS threads: 5x slower on a shared 2-core machine.)"""

    def __init__(self, obs_dim: int, n_actions: int, hidden: int, seed: int):
        import torch

        torch.set_num_threads(1)
        torch.manual_seed(seed)  # torch's default Linear initialisation
        self.torch = torch
        self.net = torch.nn.Sequential(
            torch.nn.Linear(obs_dim, hidden), torch.nn.Tanh(), torch.nn.Linear(hidden, hidden),
            torch.nn.Tanh(), torch.nn.Linear(hidden, n_actions), torch.nn.Softmax(dim=-1))
        self.rng = np.random.default_rng(seed)

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        with self.torch.no_grad():
            probs = self.net(self.torch.from_numpy(batch.obs).float()).numpy()
        cdf = np.cumsum(probs, axis=1)
        u = self.rng.random(len(cdf)) * cdf[:, -1]
        # the number of CDF entries <= u is the action; the min guards rounding at the top
        return np.minimum((cdf <= u[:, None]).sum(axis=1), cdf.shape[1] - 1)


class ScriptedPolicy:
    """Uniform random actions drawn in advance, looked up by (episode, agent, decision index)."""

    def __init__(self, n_episodes: int, n_agents: int, n_actions: int, rng: np.random.Generator,
                 per_agent: int = 256):
        self.table = rng.integers(0, n_actions, (n_episodes, n_agents, per_agent))

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        return self.table[batch.episode, batch.agent, batch.index % self.table.shape[2]]


def _policy(kind: str, env, cfg: BenchWildfireConfig, seed: int):
    if kind == "mlp":
        return MLPPolicy(env.obs_dim, env.n_actions, cfg.hidden, seed)
    return ScriptedPolicy(BATCH_EPISODES, env.n_agents, env.n_actions, np.random.default_rng(seed))


def measure(cfg: BenchWildfireConfig, seed: int) -> pd.DataFrame:
    env_cfg = WildfireConfig()
    warm = make_env(env_cfg)
    warm.rollout(_policy("scripted", warm, cfg, seed), 2, seed)  # compile, or load from cache
    rows = []
    for engine, make, episodes in (("fast", make_env, cfg.fast_episodes),
                                   ("reference", make_reference_env, cfg.reference_episodes)):
        env = make(env_cfg)
        for kind in ("mlp", "scripted"):
            policy = _policy(kind, env, cfg, seed)
            wall0, cpu0 = time.perf_counter(), time.process_time()
            rollout = evaluate(env, policy, episodes, seed)
            wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
            rows.append(dict(
                engine=engine, sim=env_cfg.label,
                policy=f"mlp-{cfg.hidden}x2-tanh" if kind == "mlp" else kind,
                batch_episodes=min(episodes, BATCH_EPISODES) if engine == "fast" else 1,
                episodes=episodes, decisions=rollout.n_decisions, seconds=wall, cpu_seconds=cpu,
                decisions_per_second=rollout.n_decisions / wall,
                episodes_per_second=episodes / wall,
                decisions_per_cpu_second=rollout.n_decisions / cpu,
                episodes_per_cpu_second=episodes / cpu))
    frame = pd.DataFrame(rows)
    reference = frame[frame.engine == "reference"].set_index("policy")
    frame["speedup_vs_reference"] = frame.decisions_per_second / frame.policy.map(
        reference.decisions_per_second)
    frame["cpu_speedup_vs_reference"] = frame.decisions_per_cpu_second / frame.policy.map(
        reference.decisions_per_cpu_second)
    return frame


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p)
    p.add_argument("--fast-episodes", type=int, help="episodes for the fast engine")
    p.add_argument("--reference-episodes", type=int, help="episodes for the SimPy reference")


def run(args: argparse.Namespace) -> int:
    cfg = for_scale(BenchWildfireConfig, args.scale, fast_episodes=args.fast_episodes,
                    reference_episodes=args.reference_episodes)
    cfg.validate()
    results = check_writable_dir(args.results_dir, "--results-dir")
    load_before = os.getloadavg()[0]
    t0 = time.perf_counter()
    frame = measure(cfg, args.seed)
    prov = provenance(cfg, command="bench-wildfire", scale=args.scale, seed=args.seed,
                      wall_seconds=time.perf_counter() - t0,
                      extra={"note": "timings vary between runs and machines; one thread",
                             "load_average_1min": [load_before, os.getloadavg()[0]]})
    write_result(results / "bench_wildfire.csv", frame, prov)
    print(frame.to_string(index=False))
    return 0
