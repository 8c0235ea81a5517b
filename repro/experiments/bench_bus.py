"""Episodes per second of the fast bus engine and its SimPy reference, measured in one run.

Both run random actions (a seeded uniform policy over the four holds), so episodes
desynchronise as in training; the fast engine's JIT compilation is excluded by a warm-up rollout.
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
from repro.envs.bus import BusConfig, make_env, make_reference_env


@dataclass(frozen=True)
class BenchConfig:
    """Episodes per engine (one batch each)."""

    fast_episodes: int = 2000
    """Episodes in the fast engine's batch."""
    reference_episodes: int = 20
    """Episodes in the SimPy reference's batch."""

    SCALES: ClassVar[dict] = {
        "smoke": dict(fast_episodes=200, reference_episodes=4),
        "quick": {},
        "paper": dict(fast_episodes=10000, reference_episodes=100),
    }


def _uniform(seed: int):
    rng = np.random.default_rng(seed)
    return lambda batch: rng.integers(0, BusConfig().n_actions, len(batch))


def measure(cfg: BenchConfig, seed: int) -> pd.DataFrame:
    make_env().rollout(_uniform(seed), 1)  # compile
    rows = []
    for engine, env, n in (("fast", make_env(), cfg.fast_episodes),
                           ("simpy", make_reference_env(), cfg.reference_episodes)):
        t0 = time.perf_counter()
        env.rollout(_uniform(seed), n)
        wall = time.perf_counter() - t0
        rows.append(dict(engine=engine, episodes=n, seconds=wall, episodes_per_s=n / wall))
    df = pd.DataFrame(rows)
    df["speedup_vs_simpy"] = df.episodes_per_s / df.episodes_per_s.iloc[1]
    return df


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p)
    p.add_argument("--fast-episodes", type=int, help="episodes for the fast engine")
    p.add_argument("--reference-episodes", type=int, help="episodes for the SimPy reference")


def run(args: argparse.Namespace) -> int:
    cfg = for_scale(BenchConfig, args.scale, fast_episodes=args.fast_episodes,
                    reference_episodes=args.reference_episodes)
    require(cfg.fast_episodes >= 1, "--fast-episodes", "an integer >= 1", cfg.fast_episodes)
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
