"""The bus policies the drivers name (No Holding, the authors' and our thresholds, a trained MLP),
made from the result files and run folders where they come from."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from repro.core.errors import UsageError, require
from repro.core.rollout import DecisionBatch, Policy
from repro.envs.bus.params import SWITCHES, BusConfig
from repro.envs.bus.policies import (AUTHORS_THRESHOLDS, ThresholdPolicy, check_thresholds,
                                     no_holding)
from repro.learn.run_folder import CHECKPOINT
from repro.learn.trained_policy import load_trained_run, policy_from_state, trained_env_config


class GreedyPolicy:
    """A trained policy acting greedily: the most probable action of its MLP (ties: the lowest).

    The figures show one episode per policy; acting greedily makes that episode the trained
    policy's exact behaviour, as it is for the deterministic baselines. The run must have been
    trained with the switches B1-B5 of ``cfg`` (they change what it observes).
    """

    def __init__(self, run: str | Path, cfg: BusConfig):
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
    try:
        row = pd.read_csv(path).query("source == 'ours'").iloc[0]
        return check_thresholds(np.array([row.T1, row.T2, row.T3], float))[0]
    except (ValueError, KeyError, IndexError, AttributeError, pd.errors.UndefinedVariableError):
        raise UsageError(param, f"a folder whose {THRESHOLDS_CSV} is the table "
                         "`make table-thresholds` writes (run it again)",
                         str(results_dir)) from None


def best_run(results_dir: str | Path) -> Path:
    """The run folder of the lambda sweep's best run (highest final return), from
    results/bus_lambda_summary.csv, written by `make fig-bus-lambda`."""
    path = Path(results_dir) / LAMBDA_SUMMARY_CSV
    if not path.exists():
        raise UsageError("--mlp-run", f"given, or {path} written first by `make fig-bus-lambda`")
    try:
        runs = pd.read_csv(path).query("policy == 'mlp-run'")
        return Path(runs.run.iloc[int(np.argmax(runs.final_iqm.to_numpy(float)))])
    except (ValueError, KeyError, IndexError, AttributeError, TypeError,
            pd.errors.UndefinedVariableError):
        raise UsageError("--mlp-run", f"given, or a {LAMBDA_SUMMARY_CSV} as `make fig-bus-lambda` "
                         "writes it (run it again)", str(path)) from None


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
