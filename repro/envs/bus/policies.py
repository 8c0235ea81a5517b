"""The bus baselines (SPEC 5.3) as batched policies, and the name -> policy map of the drivers."""

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
        t = self.thresholds[batch.episode if len(self.thresholds) > 1
                            else np.zeros(len(batch), int)]
        h = batch.obs[:, H_COLUMN][:, None]
        return (h <= t).sum(axis=1).astype(np.int64)


class GreedyPolicy:
    """A trained policy acting greedily: the most probable action of its MLP (ties: the lowest).

    The figures show one episode per policy; acting greedily makes that episode the trained
    policy's exact behaviour, as it is for the deterministic baselines.
    """

    def __init__(self, run: str | Path):
        from repro.learn.run_folder import CHECKPOINT
        from repro.learn.trained_policy import load_trained_run, policy_from_state

        state = load_trained_run(Path(run) / CHECKPOINT, "bus", "--mlp-run")
        # the generator is never drawn from: greedy actions need no randomness
        self.sampler = policy_from_state(state, np.random.default_rng(0))

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        return self.sampler.probabilities(batch.obs).argmax(axis=1).astype(np.int64)


POLICIES = ("nohold", "mlp", "thresholds")
"""Policy names the bus drivers accept, in the paper's panel order."""

THRESHOLDS_CSV = "bus_thresholds.csv"
LAMBDA_SUMMARY_CSV = "bus_lambda_summary.csv"


def read_thresholds(results_dir: str | Path, param: str = "--thresholds") -> np.ndarray:
    """T1, T2, T3 (minutes) from results/bus_thresholds.csv, written by `make table-thresholds`;
    without it, a UsageError naming ``param``, the option that could have supplied them."""
    path = Path(results_dir) / THRESHOLDS_CSV
    if not path.exists():
        if param == "--thresholds":
            raise UsageError(param, f"given, or {path} written first by `make table-thresholds`")
        raise UsageError(param, f"a folder holding {THRESHOLDS_CSV} (`make table-thresholds` "
                         "writes it)", str(results_dir))
    row = pd.read_csv(path).iloc[0]
    return np.array([row.T1, row.T2, row.T3], float)


def best_run(results_dir: str | Path) -> Path:
    """The run folder of the lambda sweep's best run (highest final return), from
    results/bus_lambda_summary.csv, written by `make fig-bus-lambda`."""
    path = Path(results_dir) / LAMBDA_SUMMARY_CSV
    if not path.exists():
        raise UsageError("--mlp-run", f"given, or {path} written first by `make fig-bus-lambda`")
    runs = pd.read_csv(path)
    runs = runs[runs.policy == "mlp-run"]
    return Path(runs.run.iloc[int(np.argmax(runs.final_iqm.to_numpy()))])


def make_policy(name: str, *, thresholds: np.ndarray | None = None,
                results_dir: str | Path = "results/paper",
                mlp_run: str | Path | None = None) -> Policy:
    """The policy called ``name``; thresholds default to the optimised ones in ``results_dir``, the
    trained MLP to the best run of the lambda sweep recorded there."""
    require(name in POLICIES, "--policy", "one of " + ", ".join(POLICIES), name)
    if name == "nohold":
        return no_holding
    if name == "mlp":
        return GreedyPolicy(best_run(results_dir) if mlp_run is None else mlp_run)
    return ThresholdPolicy(read_thresholds(results_dir) if thresholds is None else thresholds)
