"""How often the claims' 95% intervals hold the true value with as few runs as the suite has.

The claims compare intervals over 5 trained policies (or seeds). This study measures, by Monte
Carlo, the coverage of each interval kind of ``repro.runs.stats.INTERVALS`` (Student's t, the
percentile bootstrap, the expanded percentile bootstrap, the bootstrap-t) for the statistics the
claims use (the mean, the IQM, the difference of two means) at n = 3, 5 and 10 scores per group,
at the claims' level (95%) and at 98.75%, the level of each of C2's four Bonferroni intervals, on
four populations:

- ``normal``; ``lognormal`` (sigma 1, skewed); ``t3`` (Student's t with 3 degrees of freedom,
  heavy tails);
- ``suite``: the per-seed scores committed in the results folder, each group (a training
  simulator, a lambda, an estimator) standardized by its own mean and standard deviation and
  pooled, then drawn with replacement. Standardized residuals of groups of 5 are bounded
  (|z| <= 1.79), so this population is lighter-tailed than the scores' own; a group two studies
  share (runs one study reuses from another) counts twice.

The true value is the population's mean, its 25%-trimmed mean (IQM) or, for the difference of two
groups drawn from the same population, 0. Every kind sees the same samples; each (population,
statistic, n) draws from its own child stream of the root seed.

Outputs: ``interval_coverage.csv`` (one row per population, statistic, n and kind: coverage with
its binomial standard error, the shares missed below and above, the median width in population
standard deviations) and its figure.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, ClassVar

import numpy as np
import pandas as pd
from scipy import stats as sps

from repro.core.config import Validated, add_config_arguments, for_scale, given_fields
from repro.core.errors import UsageError
from repro.runs.provenance import provenance
from repro.runs.results import read_result, save_figure, write_result
from repro.runs.stats import INTERVALS, STATISTICS, coverage, iqm
from repro.studies.kit.options import (EVERY_CORE, Command, Folders, Workers, add_common,
                                       add_replot, read_for_replot, replot_figures)
from repro.studies.kit.sweep import map_tasks

NAME = "interval_coverage"
"""Stem of the result file and the figure."""
POPULATIONS = {"normal": sps.norm(), "lognormal": sps.lognorm(1.0), "t3": sps.t(3)}
"""The parametric populations; ``suite`` is built from the results folder."""
SUITE = "suite"
SUITE_SOURCES = (  # glob in the results folder, columns naming a group, score column, row filter
    ("transfer*.csv", ("simulator",), "adr_ed", None),
    ("order_reversal*.csv", ("semantics", "order", "simulator"), "adr_ed", None),
    ("learner_ablation.csv", ("setting", "simulator"), "adr_ed", None),
    ("beyond_mgae*.csv", ("env", "estimator"), "score", None),
    ("bus_*_summary.csv", ("lambda", "batch"), "final_iqm", ("policy", "mlp-run")),
)
"""Per-seed scores pooled into the ``suite`` population; summary tables are skipped unless a row
filter picks their per-run rows."""
MIN_GROUP = 3
"""Groups with fewer scores are not pooled."""


@dataclass(frozen=True)
class IntervalCoverageConfig(Validated):
    """Settings of the coverage study."""

    trials: int = 2000
    """Samples per (population, statistic, n)."""
    n_boot: int = 2000
    """Bootstrap resamples per interval (the claims' drivers use 2,000)."""
    sizes: tuple[int, ...] = (3, 5, 10)
    """Scores per group n."""
    confidences: tuple[float, ...] = (0.95, 0.9875)
    """Nominal levels: the claims' 95%, and 1 - 0.05 / 4, each interval of C2's Bonferroni
    bound over four lambdas."""
    populations: tuple[str, ...] = (*POPULATIONS, SUITE)
    """Populations the groups are drawn from: the parametric ones, and ``suite``, the per-seed
    scores of the studies in the results folder."""
    kinds: tuple[str, ...] = INTERVALS
    """Interval kinds whose coverage is measured."""
    statistics: tuple[str, ...] = STATISTICS
    """Statistics the intervals are of."""

    SCALES: ClassVar[dict] = {
        # smoke-scale studies train 1-2 seeds per setting, too few to pool: no suite population
        "smoke": dict(trials=100, n_boot=200, sizes=(3, 5), populations=tuple(POPULATIONS)),
        "quick": {},
        "paper": dict(trials=5000),
    }

    def validate(self) -> None:
        self.check(self.trials >= 10, "trials", "an integer >= 10")
        self.check(self.n_boot >= 100, "n_boot", "an integer >= 100")
        self.check(len(self.sizes) >= 1 and min(self.sizes) >= 3, "sizes",
                   "integers >= 3 (the bootstrap-t and the expanded interval need n >= 3)")
        self.check(len(self.confidences) >= 1 and all(0.5 <= c < 1 for c in self.confidences),
                   "confidences", "numbers in [0.5, 1)")
        self.check(len(self.populations) >= 1
                   and set(self.populations) <= {*POPULATIONS, SUITE}, "populations",
                   "one or more of " + ", ".join((*POPULATIONS, SUITE)))
        self.check(len(self.kinds) >= 1 and set(self.kinds) <= set(INTERVALS), "kinds",
                   "one or more of " + ", ".join(INTERVALS))
        self.check(len(self.statistics) >= 1 and set(self.statistics) <= set(STATISTICS),
                   "statistics", "one or more of " + ", ".join(STATISTICS))


def suite_pool(results: Path) -> tuple[np.ndarray, list[str]]:
    """The ``suite`` population: standardized per-seed scores of every group in SUITE_SOURCES
    found in ``results``, and the files they come from."""
    values, used = [], []
    for pattern, by, score, keep in SUITE_SOURCES:
        for path in sorted(results.glob(pattern)):
            if (keep is None) == path.stem.endswith(("_summary", "_effect", "_c9")):
                continue
            table = read_result(path)
            if keep is not None:
                table = table[table[keep[0]] == keep[1]]
            if not {*by, score} <= set(table.columns) or table.empty:
                continue
            for _, g in table.groupby(list(by), sort=False, dropna=False):
                x = g[score].to_numpy(dtype=float)
                if len(x) >= MIN_GROUP and x.std(ddof=1) > 0:
                    values.append((x - x.mean()) / x.std(ddof=1))
            used.append(path.name)
    return (np.concatenate(values) if values else np.empty(0)), used


def population(name: str, pool: np.ndarray) -> tuple[Callable, float, float, float]:
    """(draw(rng, shape), mean, IQM, standard deviation) of population ``name``."""
    if name == SUITE:
        return (lambda rng, shape: rng.choice(pool, size=shape), float(pool.mean()),
                float(iqm(pool)), float(pool.std()))
    dist = POPULATIONS[name]
    lo, hi = dist.ppf([0.25, 0.75])
    trimmed = dist.expect(lambda x: x, lb=lo, ub=hi, conditional=True)
    return (lambda rng, shape: dist.rvs(size=shape, random_state=rng), float(dist.mean()),
            float(trimmed), float(dist.std()))


def sampler(draw: Callable, n: int, groups: int) -> Callable:
    """``draw`` as :func:`repro.runs.stats.coverage` takes it: m samples of ``groups`` groups of
    n scores."""
    return lambda rng, m: tuple(draw(rng, (m, n)) for _ in range(groups))


def measure(cfg: IntervalCoverageConfig, pool: np.ndarray, seed: int,
            workers: Workers = EVERY_CORE) -> pd.DataFrame:
    """The coverage table: one row per population, statistic, n and kind. Each cell (population,
    statistic, n, level) has its own random stream, so the cells are measured in parallel
    (``map_tasks``) and the table does not depend on where or in which order."""
    cells = [(cfg, name, statistic, n, level, pool, seed) for name in cfg.populations
             for statistic in cfg.statistics
             for n, level in ((n, c) for c in cfg.confidences for n in cfg.sizes)]
    return pd.DataFrame([row for rows in map_tasks(measure_cell, cells, workers) for row in rows])


def measure_cell(cfg: IntervalCoverageConfig, name: str, statistic: str, n: int, level: float,
                 pool: np.ndarray, seed: int) -> list[dict]:
    """The rows of one cell of :func:`measure`'s table, one per interval kind."""
    draw, mean, trimmed, sd = population(name, pool)
    truth = {"mean": mean, "iqm": trimmed, "difference": 0.0}[statistic]
    key = (list((*POPULATIONS, SUITE)).index(name), STATISTICS.index(statistic), n,
           round(level * 1e4))
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=key))
    found = coverage(sampler(draw, n, 2 if statistic == "difference" else 1), truth, statistic,
                     cfg.kinds, trials=cfg.trials, confidence=level, n_boot=cfg.n_boot, rng=rng)
    return [dict(population=name, statistic=statistic, n=n, kind=kind, confidence=level,
                 trials=cfg.trials, n_boot=cfg.n_boot, truth=truth,
                 **{**r, "median_width": r["median_width"] / sd})
            for kind, r in found.items()]


def plot(table: pd.DataFrame, stem: Path, sources: list[Path]) -> None:
    """Coverage against n, one panel per statistic and level (rows) and population (columns), one
    line per kind with +- 2 standard errors, the nominal level dotted."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = list(dict.fromkeys(zip(table.statistic, table.confidence)))
    pops = list(dict.fromkeys(table.population))
    fig, axes = plt.subplots(len(rows), len(pops), figsize=(3 * len(pops), 2.4 * len(rows)),
                             sharex=True, sharey=True, squeeze=False)
    for (r, (statistic, level)), (c, pop) in ((a, b) for a in enumerate(rows)
                                              for b in enumerate(pops)):
        ax = axes[r][c]
        cell = table[(table.statistic == statistic) & (table.confidence == level)
                     & (table.population == pop)]
        for k, (kind, g) in enumerate(cell.groupby("kind", sort=False)):
            ax.errorbar(g.n + 0.08 * (k - 1.5), g.coverage, yerr=2 * g.coverage_se, marker="o",
                        ms=3, lw=1, capsize=2, label=kind)
        ax.axhline(level, color="k", lw=0.8, ls=":")
        ax.set_title(f"{statistic}, {pop}, nominal {level:.2%}", fontsize=8)
        ax.grid(True, alpha=0.3)
        if c == 0:
            ax.set_ylabel("coverage")
        if r == len(rows) - 1:
            ax.set_xlabel("scores per group n")
    axes[0][0].legend(fontsize=7)
    axes[0][0].set_xticks(sorted(table.n.unique()))
    save_figure(fig, stem, sources)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p)
    add_config_arguments(p, IntervalCoverageConfig)
    p.add_argument("--n-jobs", type=int, help="worker processes (default: all cores)")
    add_replot(p)


def configure(args: argparse.Namespace) -> Command[IntervalCoverageConfig]:
    return Command.of(args, for_scale(IntervalCoverageConfig, args.scale,
                                      **given_fields(args, IntervalCoverageConfig)))


def run(cmd: Command[IntervalCoverageConfig], folders: Folders) -> int:
    cfg, scale, seed = cmd.study, folders.scale, cmd.seed
    if cmd.replot:
        (table,) = read_for_replot(folders, f"{NAME}.csv")
        figures, sources = replot_figures(folders, f"{NAME}.csv")
        plot(table, figures / NAME, sources)
        print(f"wrote {figures / NAME}.png/.pdf")
        return 0
    figures = folders.open_figures()
    results = folders.open_results()
    pool, used = suite_pool(results)
    if SUITE in cfg.populations and len(pool) < 2 * MIN_GROUP:
        raise UsageError("--populations", f"without {SUITE} where --results-dir holds no "
                         "per-seed scores", ",".join(cfg.populations))
    t0 = time.perf_counter()
    table = measure(cfg, pool, seed, cmd.workers)
    prov = provenance(cfg, command="interval-coverage", scale=scale, seed=seed,
                      wall_seconds=time.perf_counter() - t0,
                      extra=dict(suite_pool=dict(values=len(pool), files=used)))
    sources = [write_result(results / f"{NAME}.csv", table, prov)]
    plot(table, figures / NAME, sources)
    print(table.pivot_table(index=["confidence", "population", "statistic", "n"], columns="kind",
                            values="coverage", sort=False).round(3).to_string())
    return 0
