"""The bus baselines (SPEC 5.3) as batched policies, and the name -> policy map of the drivers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from repro.core.errors import UsageError, require
from repro.core.rollout import DecisionBatch, Policy
from repro.envs.bus.params import SWITCHES, BusConfig

H_COLUMN = 1
"""Column of the headway h in the bus observation (seconds under B2, else minutes)."""

AUTHORS_THRESHOLDS = (532.79107018, 340.28721132, 262.62855417)
"""The authors' Optimized Thresholds (s), from ``optimize_heuristic()`` in their released
BusBunching/busbunchingenv.py (SPEC 5.5), sorted T1 > T2 > T3."""


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


class GreedyPolicy:
    """A trained policy acting greedily: the most probable action of its MLP (ties: the lowest).

    The figures show one episode per policy; acting greedily makes that episode the trained
    policy's exact behaviour, as it is for the deterministic baselines. The run must have been
    trained with the switches B1-B5 of ``cfg`` (they change what it observes).
    """

    def __init__(self, run: str | Path, cfg: BusConfig):
        from repro.experiments.bench_common import trained_env_config
        from repro.learn.run_folder import CHECKPOINT
        from repro.learn.trained_policy import load_trained_run, policy_from_state

        state = load_trained_run(Path(run) / CHECKPOINT, "bus", "--mlp-run")
        trained = trained_env_config(state, BusConfig)
        differ = [f for f in SWITCHES if getattr(trained, f) != getattr(cfg, f)]
        require(not differ, "--mlp-run", "a run trained with this command's switches B1-B5 "
                f"(it differs in {', '.join(differ)})", str(run))
        # the generator is never drawn from: greedy actions need no randomness
        self.sampler = policy_from_state(state, np.random.default_rng(0))

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        return self.sampler.probabilities(batch.obs).argmax(axis=1).astype(np.int64)


POLICIES = ("nohold", "authors", "thresholds", "mlp")
"""Policy names the bus drivers accept, in panel order: No Holding, the authors' thresholds, ours
(``make table-thresholds``), the trained MLP."""

THRESHOLDS_CSV = "bus_thresholds.csv"
LAMBDA_SUMMARY_CSV = "bus_lambda_summary.csv"


def read_thresholds(results_dir: str | Path, param: str = "--thresholds") -> np.ndarray:
    """Our T1, T2, T3 (s) from results/bus_thresholds.csv, written by `make table-thresholds`;
    without it, a UsageError naming ``param``, the option that could have supplied them."""
    path = Path(results_dir) / THRESHOLDS_CSV
    if not path.exists():
        if param == "--thresholds":
            raise UsageError(param, f"given, or {path} written first by `make table-thresholds`")
        raise UsageError(param, f"a folder holding {THRESHOLDS_CSV} (`make table-thresholds` "
                         "writes it)", str(results_dir))
    table = pd.read_csv(path)
    row = table[table.source == "ours"].iloc[0]
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


def make_policy(name: str, cfg: BusConfig, *, thresholds: np.ndarray | None = None,
                results_dir: str | Path = "results/paper",
                mlp_run: str | Path | None = None) -> Policy:
    """The policy called ``name`` on corridor ``cfg``; our thresholds default to the optimised
    ones in ``results_dir``, the trained MLP to the best run of the lambda sweep recorded there."""
    require(name in POLICIES, "--policy", "one of " + ", ".join(POLICIES), name)
    if name == "nohold":
        return no_holding
    if name == "mlp":
        return GreedyPolicy(best_run(results_dir) if mlp_run is None else mlp_run, cfg)
    if name == "authors":
        thresholds = np.array(AUTHORS_THRESHOLDS)
    elif thresholds is None:
        thresholds = read_thresholds(results_dir)
    return ThresholdPolicy(thresholds, headway_in_minutes=not cfg.b2_headway)
