"""The bus baselines (docs/semantics.md section 4.8) as batched policies."""

from __future__ import annotations


import numpy as np

from repro.core.errors import require
from repro.core.rollout import DecisionBatch

H_COLUMN = 1
"""Column of the headway h in the bus observation (seconds under B2, else minutes)."""

AUTHORS_THRESHOLDS = (532.79107018, 340.28721132, 262.62855417)
"""The authors' Optimized Thresholds (s), from ``optimize_heuristic()`` in their released
BusBunching/busbunchingenv.py (docs/semantics.md section 4.8), sorted T1 > T2 > T3."""


def no_holding(batch: DecisionBatch) -> np.ndarray:
    """a = 0 always."""
    return np.zeros(len(batch), np.int64)


def check_thresholds(thresholds: np.ndarray) -> np.ndarray:
    """(3,) or (E, 3) thresholds in seconds, finite and >= 0, as (E, 3); their order does not
    matter."""
    t = np.atleast_2d(np.asarray(thresholds, float))
    require(t.ndim == 2 and t.shape[1] == 3 and bool(np.all(np.isfinite(t) & (t >= 0))),
            "--thresholds", "three finite numbers >= 0, T1 T2 T3 (seconds)",
            np.asarray(thresholds).tolist())
    return t


class ThresholdPolicy:
    """Optimized Thresholds, the released rule: a = the number of thresholds T_j with h < T_j
    (strict; so T1 > T2 > T3 gives a = 0 if h >= T1, ..., 3 if h < T3, and an unknown headway,
    h = -1 under B2, gives 3).

    Thresholds are in seconds; ``headway_in_minutes`` says the observation's h is in minutes (B2
    off). With (E, 3) thresholds, episode e of the batch uses row e: a whole population of
    candidates is evaluated in one rollout.
    """

    def __init__(self, thresholds: np.ndarray, headway_in_minutes: bool = False):
        self.thresholds = check_thresholds(thresholds)
        self.scale = 60.0 if headway_in_minutes else 1.0

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        t = self.thresholds[batch.episode if len(self.thresholds) > 1
                            else np.zeros(len(batch), int)]
        h = self.scale * batch.obs[:, H_COLUMN][:, None]
        return (h < t).sum(axis=1).astype(np.int64)
