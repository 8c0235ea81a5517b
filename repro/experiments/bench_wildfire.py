"""Decisions per second of the two wildfire engines with a torch MLP policy in the loop.

One process, one thread: the fast engine (numba, one policy call per round for the whole batch)
and the SimPy reference (one policy call per decision) simulate ED episodes with the same policy,
a two-layer 32-unit tanh MLP sampling its categorical action. The fast engine is compiled (and run
once) before timing. Throughput counts recorded decisions over wall time, the policy included; the
fast engine's row also says how much of that time the policy took.
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
from repro.core.rollout import DecisionBatch
from repro.envs.wildfire import WildfireConfig, make_env, make_reference_env
from repro.experiments.wildfire_eval import evaluate


@dataclass(frozen=True)
class BenchWildfireConfig:
    """Sizes of the benchmark (the timings are the result; the scale only changes the sizes)."""

    fast_episodes: int = 4000
    """Episodes simulated by the fast engine (in batches of wildfire_eval.BATCH_EPISODES)."""
    reference_episodes: int = 30
    """Episodes simulated by the SimPy reference."""
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
    """obs -> tanh(32) -> tanh(32) -> logits; samples with its own torch Generator; counts the
    seconds it spends (so the benchmark can split policy time from engine time)."""

    def __init__(self, obs_dim: int, n_actions: int, hidden: int, seed: int):
        import torch

        self.torch = torch
        self.gen = torch.Generator().manual_seed(seed)
        torch.manual_seed(seed)
        self.net = torch.nn.Sequential(
            torch.nn.Linear(obs_dim, hidden), torch.nn.Tanh(), torch.nn.Linear(hidden, hidden),
            torch.nn.Tanh(), torch.nn.Linear(hidden, n_actions)).double()
        self.seconds = 0.0

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        t0 = time.perf_counter()
        with self.torch.no_grad():
            logits = self.net(self.torch.from_numpy(np.ascontiguousarray(batch.obs)))
            a = self.torch.multinomial(self.torch.softmax(logits, -1), 1, generator=self.gen)
        out = a[:, 0].numpy().astype(np.int64)
        self.seconds += time.perf_counter() - t0
        return out


def measure(cfg: BenchWildfireConfig, seed: int) -> pd.DataFrame:
    import torch

    torch.set_num_threads(1)
    env_cfg = WildfireConfig()
    rows = []
    for engine, make, episodes in (("fast", make_env, cfg.fast_episodes),
                                   ("reference", make_reference_env, cfg.reference_episodes)):
        env = make(env_cfg)
        if engine == "fast":  # compile (or load from cache) outside the timing
            env.rollout(MLPPolicy(env.obs_dim, env.n_actions, cfg.hidden, seed), 2, seed)
        policy = MLPPolicy(env.obs_dim, env.n_actions, cfg.hidden, seed)
        t0 = time.perf_counter()
        rollout = evaluate(env, policy, episodes, seed)
        seconds = time.perf_counter() - t0
        rows.append(dict(engine=engine, sim=env_cfg.label, policy=f"mlp-{cfg.hidden}x2-tanh",
                         episodes=episodes, decisions=rollout.n_decisions, seconds=seconds,
                         policy_seconds=policy.seconds,
                         decisions_per_second=rollout.n_decisions / seconds))
    frame = pd.DataFrame(rows)
    frame["speedup_vs_reference"] = frame.decisions_per_second / frame.decisions_per_second.iloc[1]
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
    t0 = time.perf_counter()
    frame = measure(cfg, args.seed)
    prov = provenance(cfg, command="bench-wildfire", scale=args.scale, seed=args.seed,
                      wall_seconds=time.perf_counter() - t0,
                      extra={"note": "timings vary between runs and machines; one thread"})
    write_result(results / "bench_wildfire.csv", frame, prov)
    print(frame.to_string(index=False))
    return 0
