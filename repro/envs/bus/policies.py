"""The bus baselines (SPEC 5.3) as batched policies, and the name -> policy map the drivers share."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from repro.core.errors import UsageError, require
from repro.core.rollout import DecisionBatch, Policy

H_COLUMN = 1
"""Column of the headway h (minutes) in the bus observation."""


def no_holding(batch: DecisionBatch) -> np.ndarray:
    """a = 0 always."""
    return np.zeros(len(batch), np.int64)


def check_thresholds(thresholds: np.ndarray) -> np.ndarray:
    """(3,) or (E, 3) thresholds in minutes, each row strictly decreasing (T1 > T2 > T3)."""
    t = np.atleast_2d(np.asarray(thresholds, float))
    require(t.shape[1] == 3 and bool(np.all(np.isfinite(t))), "--thresholds",
            "three finite numbers T1 T2 T3 (minutes)", np.asarray(thresholds).tolist())
    require(bool(np.all(t[:, 0] > t[:, 1]) and np.all(t[:, 1] > t[:, 2])), "--thresholds",
            "strictly decreasing (T1 > T2 > T3)", np.asarray(thresholds).tolist())
    return t


class ThresholdPolicy:
    """Optimized Thresholds: a = 0 if h > T1, 1 if T2 < h <= T1, 2 if T3 < h <= T2, 3 otherwise.

    With (E, 3) thresholds, episode e of the batch uses row e: a whole population of candidates is
    evaluated in one rollout.
    """

    def __init__(self, thresholds: np.ndarray):
        self.thresholds = check_thresholds(thresholds)

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        t = self.thresholds[batch.episode if len(self.thresholds) > 1 else np.zeros(len(batch), int)]
        h = batch.obs[:, H_COLUMN][:, None]
        return (h <= t).sum(axis=1).astype(np.int64)


POLICIES = ("nohold", "thresholds")
"""Policy names the bus drivers accept (a trained "mlp" policy plugs in through make_policy)."""

THRESHOLDS_CSV = "bus_thresholds.csv"


def read_thresholds(results_dir: str | Path) -> np.ndarray:
    """T1, T2, T3 (minutes) from results/bus_thresholds.csv, written by `make table-thresholds`."""
    path = Path(results_dir) / THRESHOLDS_CSV
    if not path.exists():
        raise UsageError("--thresholds", f"given, or {path} written first by `make table-thresholds`")
    row = pd.read_csv(path).iloc[0]
    return np.array([row.T1, row.T2, row.T3], float)


def make_policy(name: str, *, thresholds: np.ndarray | None = None,
                results_dir: str | Path = "results") -> Policy:
    """The policy called ``name``; thresholds default to the optimised ones in ``results_dir``."""
    require(name in POLICIES, "--policy", "one of " + ", ".join(POLICIES), name)
    if name == "nohold":
        return no_holding
    return ThresholdPolicy(read_thresholds(results_dir) if thresholds is None else thresholds)
