"""Evaluate a bus policy: return, discounted return, 4th-cycle loads, time to regularity.

``python -m repro bus-eval --policy {nohold,thresholds,mlp} [--thresholds T1 T2 T3] [--json]``
prints the numbers and writes nothing. The corridor is deterministic and so is every policy here
(the MLP acts greedily), so one episode is the exact value. :func:`evaluate` also takes more
episodes, for sampling policies built in code (its per-episode figures come from episode 0).
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import pandas as pd

from repro.core.errors import require
from repro.core.rollout import Policy
from repro.envs.bus import BusConfig, make_env
from repro.envs.bus.metrics import (REGULARITY_BAND_MIN, arrival_table, cycle_loads,
                                    time_to_regularity)
from repro.envs.bus.policies import POLICIES, make_policy

CYCLE = 4
"""The cycle whose loads the paper shows (steady state)."""


def policy_from_args(name: str, args: argparse.Namespace) -> Policy:
    """The named policy; --thresholds / --mlp-run, else the optimised thresholds and the best
    trained run recorded in --results-dir."""
    thresholds = None if args.thresholds is None else np.array(args.thresholds, float)
    return make_policy(name, thresholds=thresholds, results_dir=args.results_dir,
                       mlp_run=args.mlp_run)


def _finite_or_none(x: float) -> float | None:
    return x if np.isfinite(x) else None


def evaluate(policy: Policy, cfg: BusConfig, n_episodes: int = 1) -> tuple[dict, pd.DataFrame]:
    """The summary of ``n_episodes`` episodes and the arrival table of all of them."""
    roll = make_env(cfg).rollout(policy, n_episodes)
    arrivals = arrival_table(roll, cfg.n_stops)
    first = arrivals[arrivals.episode == 0]
    loads = cycle_loads(first, CYCLE)
    summary = {
        "return": float(roll.episode_return.mean()),
        "discounted_return": float(roll.discounted_path_returns(cfg.gamma).mean()),
        "episodes": n_episodes,
        # a bus that has not finished its 4th cycle by the horizon has fewer than K loads
        "loads_cycle4": [loads[loads.bus == b].sort_values("stop").load.tolist()
                         for b in range(1, cfg.n_buses + 1)],
        # null in JSON when regularity is never reached
        "time_to_regularity_min": _finite_or_none(time_to_regularity(first, cfg.headway)),
        "regularity_band_min": REGULARITY_BAND_MIN,
    }
    return summary, arrivals


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--policy", required=True, help="one of " + ", ".join(POLICIES))
    p.add_argument("--thresholds", type=float, nargs=3, metavar=("T1", "T2", "T3"),
                   help="thresholds in minutes (default: results/bus_thresholds.csv)")
    p.add_argument("--mlp-run", help="training run folder of the mlp policy "
                   "(default: the best run in results/bus_lambda_summary.csv)")
    p.add_argument("--results-dir", default="results/paper",
                   help="where bus_thresholds.csv and bus_lambda_summary.csv are read")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    for option, value, used_by in (("--thresholds", args.thresholds, "thresholds"),
                                   ("--mlp-run", args.mlp_run, "mlp")):
        require(value is None or args.policy == used_by, option, f"used with --policy {used_by}")
    policy = policy_from_args(args.policy, args)
    summary, _ = evaluate(policy, BusConfig())
    summary["policy"] = args.policy
    if args.json:
        print(json.dumps(summary))
    else:
        for key, val in summary.items():
            print(f"{key}: {val}")
    return 0


__all__ = ["evaluate", "policy_from_args", "CYCLE"]
