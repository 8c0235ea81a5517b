"""Optimized Thresholds (SPEC 5.3): T1 > T2 > T3 found by scipy's differential evolution.

The objective is the average episode return (undiscounted sum of -nu_k (h - H)^2 over the arrivals
of a 3 h episode), the same return the MLP maximises. Environment and policy are deterministic, so
one episode per candidate is exact, and a whole population is one batched rollout
(``vectorized=True``, which implies ``updating='deferred'``). The ordering is guaranteed by
optimising x = (T3, T2 - T3, T1 - T2) with positive lower bounds on the gaps. Polishing is off: the
return is piecewise constant in the thresholds, so a gradient method has nothing to follow.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd
from scipy.optimize import differential_evolution

from repro.experiments.options import add_common
from repro.core.config import for_scale
from repro.core.errors import require
from repro.core.io import check_writable_dir, provenance, write_result
from repro.envs.bus import BusConfig, make_env
from repro.envs.bus.policies import THRESHOLDS_CSV, ThresholdPolicy


@dataclass(frozen=True)
class ThresholdsConfig:
    """Differential-evolution budget and search box (minutes)."""

    popsize: int = 15
    """scipy's popsize multiplier: the population has popsize * 3 candidates."""
    maxiter: int = 60
    """Maximum generations."""
    t3_max: float = 12.0
    """T3 is searched in [0, t3_max]."""
    gap_min: float = 0.01
    """Smallest gap T2 - T3 and T1 - T2 (keeps the thresholds strictly decreasing)."""
    gap_max: float = 12.0
    """Largest gap T2 - T3 and T1 - T2."""

    SCALES: ClassVar[dict] = {
        "smoke": dict(popsize=5, maxiter=4),
        "quick": {},
        "paper": dict(popsize=20, maxiter=200),
    }

    def validate(self) -> None:
        require(self.popsize >= 2, "--popsize", "an integer >= 2", self.popsize)
        require(self.maxiter >= 1, "--maxiter", "an integer >= 1", self.maxiter)
        require(0 < self.gap_min < self.gap_max, "gap_min", "in (0, gap_max)", self.gap_min)


def to_thresholds(x: np.ndarray) -> np.ndarray:
    """(3, S) DE parameters (T3, gap2, gap1) -> (S, 3) thresholds (T1, T2, T3)."""
    t3 = x[0]
    t2 = t3 + x[1]
    return np.stack([t2 + x[2], t2, t3], axis=1)


def optimise(cfg: ThresholdsConfig, bus: BusConfig, seed: int) -> dict:
    env = make_env(bus)
    evaluations = 0  # candidates evaluated (scipy's nfev counts vectorised calls instead)

    def neg_return(x: np.ndarray) -> np.ndarray:
        nonlocal evaluations
        x = x.reshape(3, -1)
        evaluations += x.shape[1]
        roll = env.rollout(ThresholdPolicy(to_thresholds(x)), x.shape[1])
        return -roll.episode_return

    res = differential_evolution(
        neg_return, [(0.0, cfg.t3_max), (cfg.gap_min, cfg.gap_max), (cfg.gap_min, cfg.gap_max)],
        popsize=cfg.popsize, maxiter=cfg.maxiter, rng=np.random.default_rng(seed), polish=False,
        vectorized=True, updating="deferred")
    t = to_thresholds(res.x.reshape(3, 1))[0]
    best = env.rollout(ThresholdPolicy(t), 1)
    return dict(T1=t[0], T2=t[1], T3=t[2], **{"return": float(best.episode_return[0])},
                discounted_return=float(best.discounted_path_returns(bus.gamma).mean()),
                evaluations=evaluations, generations=int(res.nit), seed=seed)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p, figures=False)
    p.add_argument("--popsize", type=int, help="DE population multiplier")
    p.add_argument("--maxiter", type=int, help="DE generations")


def run(args: argparse.Namespace) -> int:
    cfg = for_scale(ThresholdsConfig, args.scale, popsize=args.popsize, maxiter=args.maxiter)
    cfg.validate()
    results = check_writable_dir(args.results_dir, "--results-dir")
    t0 = time.perf_counter()
    row = optimise(cfg, BusConfig(), args.seed)
    prov = provenance(cfg, command="bus-thresholds", scale=args.scale, seed=args.seed,
                      wall_seconds=time.perf_counter() - t0)
    write_result(results / THRESHOLDS_CSV, pd.DataFrame([row]), prov)
    print(pd.DataFrame([row]).to_string(index=False))
    return 0
