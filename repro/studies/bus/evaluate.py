"""Evaluate a bus policy: return, discounted return, the paper's load records, time to regularity.

``python -m repro bus-eval --policy {nohold,authors,thresholds,mlp,gru,gru-greedy} [--thresholds
T1 T2 T3] [--gru-run RUN] [--json]`` prints the numbers and writes nothing. The corridor is
deterministic and so is every policy here but gru (the MLP and gru-greedy act greedily), so one
episode is the exact value; gru samples its actions, so its episode is one draw. The returns are
those of the training episode (3 h); the loads and the time to regularity those of the paper's
pictures, a 6 h episode (docs/semantics.md section 6.5). :func:`evaluate` also takes more
episodes, for sampling policies built in code (its per-episode figures come from episode 0).
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import pandas as pd

from repro.core.errors import require
from repro.core.rollout import Policy
from repro.envs.bus import BusConfig, add_switch_arguments, config_from_args, make_env
from repro.envs.bus.metrics import (REGULARITY_BAND_MIN, record_loads, time_to_regularity,
                                    time_to_uniform)
from repro.learn.config import LEARNERS
from repro.studies.bus.policies import GRU_PANELS, POLICIES, picture_arrivals, policy_from_args


def _finite_or_none(x: float) -> float | None:
    return x if np.isfinite(x) else None


def evaluate(policy: Policy, cfg: BusConfig, n_episodes: int = 1) -> tuple[dict, pd.DataFrame]:
    """The summary of ``n_episodes`` episodes of ``cfg`` and of as many 6 h episodes, and the
    arrival table of the latter."""
    roll = make_env(cfg).rollout(policy, n_episodes)
    arrivals = picture_arrivals(policy, cfg, n_episodes)
    first = arrivals[arrivals.episode == 0]
    loads = record_loads(first)
    summary = {
        "return": float(roll.episode_return.mean()),
        "discounted_return": float(roll.discounted_path_returns(cfg.gamma).mean()),
        "episodes": n_episodes,
        "loads_records_40_50": [loads[loads.bus == b].load.tolist()
                                for b in range(1, cfg.n_buses + 1)],
        # null in JSON when never reached
        "time_to_uniform_min": _finite_or_none(time_to_uniform(first, cfg.headway)),
        "time_to_regularity_min": _finite_or_none(time_to_regularity(first, cfg.headway)),
        "regularity_band_min": REGULARITY_BAND_MIN,
    }
    return summary, arrivals


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--policy", required=True, help="one of " + ", ".join(POLICIES))
    p.add_argument("--thresholds", type=float, nargs=3, metavar=("T1", "T2", "T3"),
                   help="thresholds in seconds (default: ours in results/bus_thresholds.csv)")
    p.add_argument("--mlp-run", help="training run folder of the mlp policy "
                   "(default: the best run in results/bus_lambda_summary.csv)")
    p.add_argument("--gru-run", help="training run folder of the gru and gru-greedy policies "
                   "(gru samples its actions, from the stream of the run's name)")
    p.add_argument("--learner", choices=tuple(LEARNERS),
                   help="the mlp policy is the best run of this learner's lambda "
                   "sweep: " + ", ".join(LEARNERS) + " (default authors)")
    p.add_argument("--results-dir", default="results/paper",
                   help="where bus_thresholds.csv and bus_lambda_summary.csv are read")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    add_switch_arguments(p)


def run(args: argparse.Namespace) -> int:
    for option, value, used_by in (("--thresholds", args.thresholds, ("thresholds",)),
                                   ("--mlp-run", args.mlp_run, ("mlp",)),
                                   ("--gru-run", args.gru_run, GRU_PANELS)):
        require(value is None or args.policy in used_by, option,
                f"used with --policy {' or '.join(used_by)}")
    cfg = config_from_args(args)
    policy = policy_from_args(args.policy, args, cfg)
    summary, _ = evaluate(policy, cfg)
    summary["policy"] = args.policy
    if args.json:
        print(json.dumps(summary))
    else:
        for key, val in summary.items():
            print(f"{key}: {val}")
    return 0


__all__ = ["evaluate"]
