"""Race conditions in fixed-step simulation (paper Table "nvdt", claim C10; docs/semantics.md
section 6.6).

N event times are drawn i.i.d. from p(t). A race occurs when two or more fall into the same interval
[k dT, (k+1) dT) of a grid anchored at 0. For each N the driver finds, by bisection in log dT, the
largest dT whose race probability stays below delta, and fits log dT = log alpha - beta log N by
OLS.

Beyond the paper, the race probability is also computed exactly. With bin probabilities p_b, the
probability of no race is N! e_N(p), e_N the elementary symmetric polynomial. Writing G_n = n! e_n
and P_k = sum_b p_b^k (power sums), Newton's identities become

    G_n = sum_{k>=1} (-1)^(k+1) P_k (n-1)!/(n-k)! G_{n-k},    G_0 = 1,

whose terms shrink like (n max_b p_b)^(k-1), so a handful of power sums give every G_n to machine
precision. The pairwise term P_2 n(n-1) dominates for large N, so dT ~ N^-2 asymptotically; over
N = 2..20 the higher terms still matter, which is why the fitted beta is about 2.2.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import ClassVar

import numpy as np
import pandas as pd

from repro.core.config import Validated, add_config_arguments, for_scale, given_fields
from repro.core.errors import UsageError, require
from repro.envs.renewal.distributions import DISTRIBUTIONS
from repro.runs.progress import progress
from repro.runs.provenance import provenance
from repro.runs.results import save_figure, write_result
from repro.studies.kit.options import (Command, Folders, add_common, add_replot, read_for_replot,
                                       replot_figures)
from repro.studies.races.study import (exact_safe_dts, fit_power_law, largest_safe_dt,
                                       race_probability_exact, race_probability_mc)


MAX_EVENT_TIMES = 200_000_000
"""Largest n_sets x n_max: 1.6 GB of event times (the paper's study needs 200,000)."""


@dataclass(frozen=True)
class RaceConfig(Validated):
    """Settings of the race-condition study; the defaults are the paper's (the study is cheap)."""

    n_sets: int = 10_000
    """Monte Carlo sets of N event times drawn for each N (the same sets serve every dT)."""
    n_min: int = 2
    """Smallest number of agents."""
    n_max: int = 20
    """Largest number of agents in the paper's fit."""
    delta: float = 0.1
    """Race probability that dT must keep below."""
    distributions: tuple[str, ...] = ("exponential", "chi2", "gamma")
    """Event-time distributions (keys of DISTRIBUTIONS)."""
    bisection_steps: int = 40
    """Halvings of the log-dT bracket (a factor 1e8 bracket ends below 1e-4 relative width)."""
    exact_n: tuple[int, ...] = (2, 3, 4, 5, 7, 10, 14, 20, 30, 50, 70, 100)
    """Agent counts for the exact (sampling-free) curve, reaching well past the paper's range."""

    ALIASES: ClassVar[dict[str, str]] = {"distribution": "distributions"}
    """``--distribution chi2 --distribution gamma``, the older flag, still taken."""

    SCALES: ClassVar[dict] = {
        "smoke": dict(exact_n=(2, 3, 5, 10, 20, 30, 50)),
        "quick": {},
        "paper": dict(exact_n=(2, 3, 4, 5, 7, 10, 14, 20, 30, 50, 70, 100, 150, 200, 300)),
    }

    def validate(self) -> None:
        self.check(self.n_sets >= 1, "n_sets", "an integer >= 1")
        self.check(self.n_min >= 2, "n_min", "an integer >= 2")
        self.check(self.n_max >= self.n_min + 1, "n_max", "an integer > --n-min")
        # the event times of one N are held at once: 8 bytes each, a few copies while sorting
        self.check(self.n_sets * self.n_max <= MAX_EVENT_TIMES, "n_sets",
                   f"at most {MAX_EVENT_TIMES:,} / --n-max (the event times of one N, 8 bytes "
                   "each, are held in memory)")
        self.check(0.0 < self.delta < 1.0, "delta", "in (0, 1)")
        for d in self.distributions:
            require(d in DISTRIBUTIONS, "--distributions", "one of " + ", ".join(DISTRIBUTIONS), d)
        self.check(self.bisection_steps >= 1, "bisection_steps", "an integer >= 1")
        self.check(len(self.exact_n) >= 1 and min(self.exact_n) >= 2, "exact_n",
                   "one or more integers >= 2")


def run_study(cfg: RaceConfig, seed: int) -> dict[str, pd.DataFrame]:
    """Compute every table of the study (pure: no files are touched)."""
    streams = np.random.SeedSequence(seed).spawn(len(cfg.distributions))
    table, points, exact_rows, ranges = [], [], [], []
    for key, ss in zip(cfg.distributions, streams):
        dist = DISTRIBUTIONS[key]
        ns = np.arange(cfg.n_min, cfg.n_max + 1)
        n_streams = ss.spawn(len(ns))
        dts = []
        hi = dist.isf(1e-9) * 10  # one bin holds every time: a race for sure
        for n, nss in progress(zip(ns, n_streams), f"race MC {key}", total=len(ns)):
            times = np.sort(dist.sample(np.random.default_rng(nss), (cfg.n_sets, int(n))), axis=1)
            gaps = np.diff(times, axis=1)
            lo = float(gaps[gaps > 0].min()) / 4  # below the smallest gap: no set can race
            dt = largest_safe_dt(partial(race_probability_mc, times), cfg.delta, lo, hi,
                                 cfg.bisection_steps)
            dts.append(dt)
            points.append(dict(distribution=dist.name, parameters=dist.parameters, n=int(n),
                               dt_mc=dt, race_prob_mc=race_probability_mc(times, dt),
                               race_prob_exact=race_probability_exact(dist, dt, int(n))))
        beta, se, alpha = fit_power_law(ns, np.array(dts))
        table.append(dict(distribution=dist.name, parameters=dist.parameters, beta=beta,
                          beta_se=se, alpha=alpha, n_sets=cfg.n_sets, delta=cfg.delta,
                          n_min=cfg.n_min, n_max=cfg.n_max))

        exact_dt = exact_safe_dts(dist, cfg.exact_n, cfg.delta)
        en = np.array(sorted(exact_dt))
        edt = np.array([exact_dt[n] for n in en])
        local = np.gradient(-np.log(edt), np.log(en))
        for n, d, b in zip(en, edt, local):
            exact_rows.append(dict(distribution=dist.name, parameters=dist.parameters, n=int(n),
                                   dt_exact=d, local_beta=b))
        for lo_n, hi_n in ((cfg.n_min, cfg.n_max), (cfg.n_max, int(en.max()))):
            sel = (en >= lo_n) & (en <= hi_n)
            if sel.sum() >= 3:
                b, s, a = fit_power_law(en[sel], edt[sel])
                ranges.append(dict(distribution=dist.name, parameters=dist.parameters,
                                   n_min=lo_n, n_max=hi_n, method="exact", beta=b, beta_se=s,
                                   alpha=a))
    return {
        "table_race": pd.DataFrame(table),
        "race_dt_vs_n": pd.DataFrame(points),
        "race_exact": pd.DataFrame(exact_rows),
        "race_beta_ranges": pd.DataFrame(ranges),
    }


def plot(tables: dict[str, pd.DataFrame], stem: Path, sources: list[Path]) -> None:
    """Left: the largest safe dT against N per distribution, with our beta and the paper's
    (Table nvdt), each with its standard error; right: the exact curve's local exponent.
    ``sources``: the CSVs of the tables drawn (:data:`FIGURE_TABLES`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from repro.paper import RACE_BETA

    pts, fits, exact = tables["race_dt_vs_n"], tables["table_race"], tables["race_exact"]
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(7.0, 3.2))
    for (name, grp), color in zip(pts.groupby("distribution", sort=False), ("C0", "C1", "C2")):
        fit = fits[fits.distribution == name].iloc[0]
        ex = exact[exact.distribution == name]
        paper = (f"; paper {RACE_BETA[name][0]:.3f} ({RACE_BETA[name][1]:.3f})"
                 if name in RACE_BETA else "; not in the paper")
        ax.loglog(grp.n, grp.dt_mc, "o", color=color, ms=3,
                  label=f"{name} ({fit.parameters}): $\\beta$ = {fit.beta:.3f} "
                        f"({fit.beta_se:.3f}){paper}")
        n_line = np.linspace(grp.n.min(), grp.n.max(), 50)
        ax.loglog(n_line, fit.alpha * n_line ** -fit.beta, "-", color=color, lw=1)
        ax.loglog(ex.n, ex.dt_exact, ":", color=color, lw=1.5)
        ax2.semilogx(ex.n, ex.local_beta, "-o", color=color, ms=2.5, label=name)
    ax.set_xlabel("Number of agents $N$", fontsize=8)
    ax.set_ylabel(r"Largest $\Delta T$ with $P(\mathrm{race}) < \delta$", fontsize=8)
    ax.set_title("Monte Carlo (points), OLS fit (lines), exact (dotted);\n"
                 "$\\beta$: ours; the paper's (its table nvdt); (standard error)", fontsize=8)
    ax.legend(fontsize=5.5, loc="lower left")
    ax.grid(True, which="both", alpha=0.3)
    ax2.axhline(2.0, color="k", lw=0.8, ls="--")
    ax2.set_xlabel("Number of agents $N$", fontsize=8)
    ax2.set_ylabel(r"local exponent $-d\log\Delta T / d\log N$ (exact)", fontsize=8)
    ax2.legend(fontsize=6)
    ax2.grid(True, which="both", alpha=0.3)
    for a in (ax, ax2):
        a.tick_params(labelsize=7)
    save_figure(fig, stem, sources)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p)
    add_config_arguments(p, RaceConfig)
    p.add_argument("--no-figure", action="store_true", help="write the CSVs only")
    add_replot(p)


FIGURE_TABLES = ("race_dt_vs_n", "table_race", "race_exact")
"""The tables the figure draws, the first its name."""


def configure(args: argparse.Namespace) -> Command[RaceConfig]:
    return Command.of(args, for_scale(RaceConfig, args.scale, **given_fields(args, RaceConfig)))


def run(cmd: Command[RaceConfig], folders: Folders) -> int:
    cfg, scale, seed = cmd.study, folders.scale, cmd.seed
    if cmd.replot:
        names = [f"{name}.csv" for name in FIGURE_TABLES]
        read = read_for_replot(folders, *names)
        figures, sources = replot_figures(folders, *names)
        plot(dict(zip(FIGURE_TABLES, read)), figures / FIGURE_TABLES[0], sources)
        print(f"wrote {figures / FIGURE_TABLES[0]}.png/.pdf")
        return 0
    figures = folders.open_figures() if cmd.figure else None
    results = folders.open_results()
    t0 = time.perf_counter()
    tables = run_study(cfg, seed)
    wall = time.perf_counter() - t0
    for name, frame in tables.items():
        prov = provenance(cfg, command="race", scale=scale, seed=seed, wall_seconds=wall)
        write_result(results / f"{name}.csv", frame, prov)
    if figures is not None:
        plot(tables, figures / FIGURE_TABLES[0],
             [results / f"{name}.csv" for name in FIGURE_TABLES])
    print(tables["table_race"].to_string(index=False))
    return 0


__all__ = ["RaceConfig", "run_study", "DISTRIBUTIONS", "UsageError"]
