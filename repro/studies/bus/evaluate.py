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
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from repro.core.errors import refuse_unused, require
from repro.core.rollout import Policy
from repro.envs.bus import BusConfig, add_switch_arguments, config_from_args, make_env
from repro.envs.bus.metrics import (REGULARITY_BAND_MIN, record_loads, time_to_regularity,
                                    time_to_uniform)
from repro.learn.config import LEARNERS
from repro.studies.bus.policies import (GRU_PANELS, POLICIES, PolicySources, picture_arrivals,
                                        semantics_folder)


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


RESULTS_DIR = "results/paper"
"""Where the thresholds and mlp policies are read from without --results-dir."""


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
    p.add_argument("--results-dir", help="where bus_thresholds.csv and bus_lambda_summary.csv "
                   f"are read (default: {RESULTS_DIR}; of another semantics than the released "
                   "simulator's, its subfolder named for them, e.g. corrected/)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    add_switch_arguments(p)


@dataclass(frozen=True)
class EvalConfig:
    """What ``bus-eval`` evaluates, and how it prints it."""

    policy: str
    """The policy's name (``--policy``)."""
    sources: PolicySources
    """Where a trained or optimised policy comes from."""
    results_dir: Path
    """Where the optimised thresholds and the best trained run are read (``--results-dir``, its
    subfolder of the corridor's semantics: :func:`~repro.studies.bus.policies.semantics_folder`)."""
    json: bool
    """Print one JSON object (``--json``)."""
    bus: BusConfig
    """The corridor, its switches B1-B5 as given."""


def configure(args: argparse.Namespace) -> EvalConfig:
    """The settings of :func:`add_arguments`'s options; a UsageError for a bad policy name or an
    option the policy does not use."""
    require(args.policy in POLICIES, "--policy", "one of " + ", ".join(POLICIES), args.policy)
    own_thresholds = args.policy == "thresholds" and args.thresholds is None
    best_mlp = args.policy == "mlp" and args.mlp_run is None
    refuse_unused(
        ("--thresholds", args.thresholds, args.policy == "thresholds",
         "with --policy thresholds"),
        ("--mlp-run", args.mlp_run, args.policy == "mlp", "with --policy mlp"),
        ("--gru-run", args.gru_run, args.policy in GRU_PANELS,
         "with --policy " + " or ".join(GRU_PANELS)),
        ("--learner", args.learner, best_mlp,
         "with --policy mlp without --mlp-run (it picks the learner's best run)"),
        ("--results-dir", args.results_dir, own_thresholds or best_mlp,
         "with --policy thresholds without --thresholds, or mlp without --mlp-run (they read "
         "it)"))
    bus = config_from_args(args)
    return EvalConfig(policy=args.policy, sources=PolicySources.of(args),
                      results_dir=semantics_folder(Path(args.results_dir or RESULTS_DIR), bus),
                      json=args.json, bus=bus)


def run(cfg: EvalConfig) -> int:
    policy = cfg.sources.policy(cfg.policy, cfg.bus, cfg.results_dir)
    summary, _ = evaluate(policy, cfg.bus)
    summary["policy"] = cfg.policy
    if cfg.json:
        print(json.dumps(summary))
    else:
        for key, val in summary.items():
            print(f"{key}: {val}")
    return 0


__all__ = ["evaluate"]
