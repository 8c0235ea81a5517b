"""Optimized Thresholds by scipy's differential evolution, the authors' set-up (docs/semantics.md
section 4.8).

As in ``optimize_heuristic()`` of the released BusBunching/busbunchingenv.py: three thresholds,
each searched in [0, 3H] seconds, in any order (the rule counts the thresholds above h, so the
order does not matter; reported sorted, T1 > T2 > T3); the objective is the undiscounted return of
one 3 h episode (deterministic corridor and policy, so one episode is exact). A whole population
is one batched rollout of the fast engine (``vectorized=True``, which implies
``updating='deferred'``). Polishing is off: the return is piecewise constant in the thresholds, so
a gradient method has nothing to follow. The CSV holds our thresholds and the authors' (source
``ours`` / ``authors``), each with its return on the same corridor.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd
from scipy.optimize import differential_evolution

from repro.core.config import Validated, add_config_arguments, for_scale, given_fields, to_dict
from repro.envs.bus import BusConfig, add_switch_arguments, config_from_args, make_env
from repro.envs.bus.policies import AUTHORS_THRESHOLDS, ThresholdPolicy
from repro.runs.provenance import provenance
from repro.runs.results import write_result
from repro.studies.bus.policies import BUS_VARIANTS, THRESHOLDS_CSV, semantics_folders
from repro.studies.kit.options import Command, Folders, add_common


@dataclass(frozen=True)
class ThresholdsConfig(Validated):
    """Differential-evolution budget (scipy's defaults at paper scale, as the authors ran it)."""

    popsize: int = 15
    """scipy's popsize multiplier: the population has popsize * 3 candidates."""
    maxiter: int = 100
    """Maximum generations (scipy stops earlier once the population has converged)."""

    SCALES: ClassVar[dict] = {
        "smoke": dict(popsize=5, maxiter=4),
        "quick": {},
        "paper": dict(maxiter=1000),
    }

    def validate(self) -> None:
        self.check(self.popsize >= 2, "popsize", "an integer >= 2")
        self.check(self.maxiter >= 1, "maxiter", "an integer >= 1")


def returns(bus: BusConfig, thresholds: np.ndarray) -> np.ndarray:
    """(S,) undiscounted return of one episode per row of (S, 3) thresholds (s)."""
    policy = ThresholdPolicy(thresholds, headway_in_minutes=not bus.b2_headway)
    return make_env(bus).rollout(policy, len(thresholds)).episode_return


def optimise(cfg: ThresholdsConfig, bus: BusConfig, seed: int) -> pd.DataFrame:
    """Our thresholds beside the authors', with their returns and discounted returns."""
    evaluations = 0  # candidates evaluated (scipy's nfev counts vectorised calls instead)

    def neg_return(x: np.ndarray) -> np.ndarray:
        nonlocal evaluations
        evaluations += x.shape[1]
        return -returns(bus, x.T)

    h_max = 3 * 60.0 * bus.headway
    res = differential_evolution(neg_return, [(0.0, h_max)] * 3, popsize=cfg.popsize,
                                 maxiter=cfg.maxiter, rng=np.random.default_rng(seed),
                                 polish=False, vectorized=True, updating="deferred")
    rows = []
    for source, t in (("ours", res.x), ("authors", np.array(AUTHORS_THRESHOLDS))):
        t = np.sort(t)[::-1]
        roll = make_env(bus).rollout(
            ThresholdPolicy(t, headway_in_minutes=not bus.b2_headway), 1)
        rows.append(dict(source=source, T1=t[0], T2=t[1], T3=t[2],
                         **{"return": float(roll.episode_return[0])},
                         discounted_return=float(roll.discounted_path_returns(bus.gamma).mean())))
    table = pd.DataFrame(rows)
    table["evaluations"] = [evaluations, 0]
    table["generations"] = [int(res.nit), 0]
    return table


VARIANTS = BUS_VARIANTS
"""The options that choose the corridor's semantics, and so the results' folder, not the search's
settings (read by the command line)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p, figures=False)
    add_switch_arguments(p)
    add_config_arguments(p, ThresholdsConfig)


def configure(args: argparse.Namespace) -> Command[tuple[ThresholdsConfig, BusConfig]]:
    cfg = for_scale(ThresholdsConfig, args.scale, **given_fields(args, ThresholdsConfig))
    return Command.of(args, (cfg, config_from_args(args)))


def run(cmd: Command[tuple[ThresholdsConfig, BusConfig]], folders: Folders) -> int:
    (cfg, bus), seed = cmd.study, cmd.seed
    results = semantics_folders(folders, bus).open_results()
    t0 = time.perf_counter()
    table = optimise(cfg, bus, seed)
    prov = provenance(cfg, command="bus-thresholds", scale=folders.scale, seed=seed,
                      wall_seconds=time.perf_counter() - t0, extra={"bus": to_dict(bus)})
    write_result(results / THRESHOLDS_CSV, table, prov)
    print(table.to_string(index=False))
    return 0
