"""What event-driven and time-stepped simulation cost as the number of agents grows (claim C11).

The paper argues, without measuring, that a fixed-step simulator must shrink dT as alpha N^-beta
(beta ~ 2.2, the race study) to keep the race probability below delta, so its compute grows like
N^2.2, while an event-driven simulator's grows about linearly. This driver measures it on the
N-agent renewal process of ``repro.envs.renewal``: for each N, dT is the largest step whose exact
race probability (``repro.studies.races.race``) is below delta, and the process is simulated for a
fixed duration by

- ``event_driven``: work = events processed;
- ``rounding_fixed_step``: the simulator used for training (event times rounded up to the dT grid,
  still jumping from event to event); work = events processed, independent of dT;
- ``time_stepped``: advances by dT and visits every agent each step; work = steps (what the paper
  counts, ~N^beta) and agent visits (steps x N, ~N^(1+beta)).

Outputs: ``scaling.csv`` (work counts, deterministic for a seed), ``scaling_wall.csv`` (median wall
seconds over repeats, machine-dependent) and ``scaling_fit.csv`` (log-log OLS exponents of every
measure against N, over all N, N <= 20 and N >= 20; its ``wall_seconds`` rows are
machine-dependent, the others deterministic). Wall-time exponents over all N are flattened by fixed
per-call overheads at small N; the N >= 20 fits show the asymptotic growth.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, ClassVar

import numpy as np
import pandas as pd
from scipy import special

from repro.core.config import Validated, add_config_arguments, for_scale, given_fields
from repro.core.errors import require
from repro.core.rollout import episode_streams
from repro.envs.renewal import (Outcome, StreamDraws, draw_inter_event_times, simulate_events,
                                simulate_steps)
from repro.envs.renewal.distributions import DISTRIBUTIONS, Distribution
from repro.runs.memory import require_memory
from repro.runs.progress import progress
from repro.runs.provenance import provenance
from repro.runs.results import save_figure, write_result
from repro.studies.kit.options import (Command, Folders, add_common, add_replot, read_for_replot,
                                       replot_figures)
from repro.studies.races.study import exact_safe_dts, fit_power_law

SIMULATORS = ("event_driven", "rounding_fixed_step", "time_stepped")
WORK_MEASURES = {
    "event_driven": ("events",),
    "rounding_fixed_step": ("events",),
    "time_stepped": ("steps", "agent_visits"),
}
"""The work each simulator does, by the columns of scaling.csv that count it."""


@dataclass(frozen=True)
class ScalingConfig(Validated):
    """Settings of the scaling measurement."""

    n_agents: tuple[int, ...] = (2, 3, 4, 5, 7, 10, 14, 20, 30, 50, 70, 100)
    """Agent counts (roughly log-spaced, so that every decade weighs alike in the log-log fit)."""
    delta: float = 0.1
    """Race probability that dT must keep below (the paper's)."""
    duration: float = 100.0
    """Simulated duration, the same for every N and distribution."""
    distributions: tuple[str, ...] = ("exponential", "chi2", "gamma")
    """Inter-event time distributions (keys of race.DISTRIBUTIONS)."""
    repeats: int = 5
    """Timed runs per simulator and N; the median is reported."""
    split_n: int = 20
    """Exponents are also fitted over N <= this (the paper's range) and N >= this (large N, where
    fixed per-call overheads no longer flatten the wall-time exponents)."""

    ALIASES: ClassVar[dict[str, str]] = {"distribution": "distributions"}
    """``--distribution chi2 --distribution gamma``, the older flag, still taken."""

    SCALES: ClassVar[dict] = {
        "smoke": dict(n_agents=(2, 3, 5, 8, 12), duration=20.0, distributions=("exponential",),
                      repeats=1),
        "quick": {},
        "paper": dict(n_agents=tuple(range(2, 21)) + (30, 50, 70, 100, 140, 200), repeats=7),
    }

    def validate(self) -> None:
        self.check(len(self.n_agents) >= 3 and min(self.n_agents) >= 2
                and len(set(self.n_agents)) == len(self.n_agents), "n_agents",
                   "at least 3 distinct integers >= 2")
        self.check(0.0 < self.delta < 1.0, "delta", "in (0, 1)")
        self.check(self.duration > 0 and math.isfinite(self.duration), "duration",
                   "a finite number > 0")
        for d in self.distributions:
            require(d in DISTRIBUTIONS, "--distributions", "one of " + ", ".join(DISTRIBUTIONS), d)
        self.check(self.repeats >= 1, "repeats", "an integer >= 1")
        self.check(self.split_n >= 2, "split_n", "an integer >= 2")


WORK_LIMIT = 10**12
"""Time-stepped agent visits a measurement may ask for, in all: about 17 min at the simulator's
10^9 visits per second (the paper scale asks for about 3 x 10^10)."""


def safe_dt_estimate(dist: Distribution, n: int, delta: float) -> float:
    """About the largest dT with P(race) < delta among ``n`` agents, from the birthday bound
    P(race) ~ 1 - exp(-C(n, 2) dT int f^2) (within 1% of the exact dT at N = 20 and 200 for the
    three distributions); computed in microseconds where the exact one takes O(1/dT)."""
    k, theta = dist.shape, dist.scale  # a gamma law: int f^2 = G(2k-1) / (G(k)^2 2^(2k-1) theta)
    collide = math.exp(special.gammaln(2 * k - 1) - 2 * special.gammaln(k)
                       - (2 * k - 1) * math.log(2)) / theta
    return -math.log1p(-delta) / (n * (n - 1) / 2 * collide)


def check_work(cfg: ScalingConfig) -> None:
    """Refuse, before any work, a measurement the machine cannot do: the time-stepped simulator's
    agent visits over every N, distribution and repeat (at least half the estimate of
    :func:`safe_dt_estimate`) beyond :data:`WORK_LIMIT`, or event times of one N beyond memory."""
    big_n = max(cfg.n_agents) > max(ScalingConfig.SCALES["paper"]["n_agents"])
    param, got = ("--n-agents", list(cfg.n_agents)) if big_n else ("--duration", cfg.duration)
    visits = sum((cfg.repeats + 1) * n * cfg.duration / (2 * safe_dt_estimate(
        DISTRIBUTIONS[key], n, cfg.delta)) for key in cfg.distributions for n in cfg.n_agents)
    require(visits <= WORK_LIMIT, param, f"a measurement of at most {WORK_LIMIT:.0e} time-stepped "
            f"agent visits in all (these agent counts and duration need at least {visits:.1e})",
            got)
    event_times = max(n * (cfg.duration / DISTRIBUTIONS[key].mean + 16)
                      for key in cfg.distributions for n in cfg.n_agents)
    require_memory(2 * 8 * event_times, param, got, "the event times of one N")


def runners(draws: StreamDraws, duration: float, dt: float) -> dict[str, Callable[[], Outcome]]:
    """The three simulators on the same draws."""
    return {
        "event_driven": lambda: simulate_events(draws, duration),
        "rounding_fixed_step": lambda: simulate_events(draws, duration, dt),
        "time_stepped": lambda: simulate_steps(draws, duration, dt),
    }


def median_wall(run: Callable[[], Outcome], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        run()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def fit_rows(work: pd.DataFrame, wall: pd.DataFrame, split_n: int) -> pd.DataFrame:
    """Log-log OLS exponent of every measure against N: over all N ("all"), N <= split_n
    ("small") and N >= split_n ("large"); a range with fewer than 3 agent counts is skipped."""
    series = []
    for (key, sim), grp in work.groupby(["distribution", "simulator"], sort=False):
        for m in WORK_MEASURES[sim]:
            series.append((key, sim, m, grp.n.to_numpy(), grp[m].to_numpy(dtype=float)))
    for (key, sim), grp in wall.groupby(["distribution", "simulator"], sort=False):
        series.append((key, sim, "wall_seconds", grp.n.to_numpy(), grp.wall_seconds.to_numpy()))
    rows = []
    for key, sim, measure, n, y in series:
        ranges = {"all": n > 0, "small": n <= split_n, "large": n >= split_n}
        for name, sel in ranges.items():
            if sel.sum() < 3 or (name != "all" and sel.all()):
                continue
            beta, se, alpha = fit_power_law(n[sel], y[sel])  # fits y = alpha N^-beta
            rows.append(dict(distribution=key, simulator=sim, measure=measure, fit_range=name,
                             n_min=int(n[sel].min()), n_max=int(n[sel].max()), exponent=-beta,
                             exponent_se=se, prefactor=alpha))
    return pd.DataFrame(rows)


def run_study(cfg: ScalingConfig, seed: int) -> dict[str, pd.DataFrame]:
    """Every table of the measurement (no files are touched)."""
    ns = tuple(sorted(cfg.n_agents))
    work, wall = [], []
    streams = np.random.SeedSequence(seed).spawn(len(cfg.distributions))
    for key, ss in zip(cfg.distributions, streams):
        dist = DISTRIBUTIONS[key]
        dts = exact_safe_dts(DISTRIBUTIONS[key], ns, cfg.delta)
        for n, episode in progress(zip(ns, episode_streams(ss, len(ns))), f"scaling {key}",
                                   total=len(ns)):
            draws = draw_inter_event_times(dist, n, cfg.duration, episode)
            for sim, run in runners(draws, cfg.duration, dts[n]).items():
                out = run()
                is_ts = sim == "time_stepped"
                work.append(dict(distribution=key, n=n, dt=dts[n], duration=cfg.duration,
                                 simulator=sim, events=out.events, tied_events=out.tied_events,
                                 steps=out.steps if is_ts else pd.NA,
                                 agent_visits=out.agent_visits if is_ts else pd.NA))
                wall.append(dict(distribution=key, n=n, simulator=sim, repeats=cfg.repeats,
                                 wall_seconds=median_wall(run, cfg.repeats)))
    work_df = pd.DataFrame(work).astype({"steps": "Int64", "agent_visits": "Int64"})
    wall_df = pd.DataFrame(wall)
    return {"scaling": work_df, "scaling_wall": wall_df,
            "scaling_fit": fit_rows(work_df, wall_df, cfg.split_n)}


def warm_up() -> None:
    """Compile (or load from cache) every kernel, so that no timing includes compilation."""
    draws = StreamDraws(np.ones(4), np.array([0, 2, 4], dtype=np.int64))
    for run in runners(draws, 1.5, 0.5).values():
        run()


SERIES = [("event_driven", "events", "ED: events", "C0", "o"),
          ("rounding_fixed_step", "events", "rounding FS: events", "C2", "x"),
          ("time_stepped", "steps", "time-stepped: steps", "C1", "o"),
          ("time_stepped", "agent_visits", "time-stepped: agent visits", "C3", "o")]
"""(simulator, measure, label, colour, marker) of the work panels."""
WALL_SERIES = [("event_driven", "wall_seconds", "ED", "C0", "o"),
               ("rounding_fixed_step", "wall_seconds", "rounding FS", "C2", "x"),
               ("time_stepped", "wall_seconds", "time-stepped", "C1", "o")]


def plot(tables: dict[str, pd.DataFrame], stem: Path, sources: list[Path]) -> None:
    """Work (top) and wall time (bottom) against N per distribution, with the fitted power laws;
    ``sources``: the CSVs of the three tables drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    work, wall, fit = tables["scaling"], tables["scaling_wall"], tables["scaling_fit"]
    keys = list(dict.fromkeys(work.distribution))
    fig, axes = plt.subplots(2, len(keys), figsize=(4.2 * len(keys), 7.5), squeeze=False)
    full = fit[fit.fit_range == "all"]
    for col, key in enumerate(keys):
        for ax, frame, series in ((axes[0, col], work, SERIES), (axes[1, col], wall, WALL_SERIES)):
            for sim, measure, label, color, marker in series:
                pts = frame[(frame.distribution == key) & (frame.simulator == sim)]
                f = full[(full.distribution == key) & (full.simulator == sim)
                         & (full.measure == measure)].iloc[0]
                ax.loglog(pts.n, pts[measure].astype(float), marker, color=color, ms=5,
                          label=f"{label}: $N^{{{f.exponent:.2f}}}$")
                n_line = np.geomspace(pts.n.min(), pts.n.max(), 50)
                ax.loglog(n_line, f.prefactor * n_line ** f.exponent, "-", color=color, lw=1)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
            ax.set_xlabel("Number of agents $N$")
        d = DISTRIBUTIONS[key]
        axes[0, col].set_title(f"{d.name} ({d.parameters}), work", fontsize=9)
        axes[1, col].set_title(f"{d.name}, median wall seconds", fontsize=9)
    axes[0, 0].set_ylabel("operations per simulated duration")
    axes[1, 0].set_ylabel("seconds")
    save_figure(fig, stem, sources)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p)
    add_config_arguments(p, ScalingConfig)
    p.add_argument("--no-figure", action="store_true", help="write the CSVs only")
    add_replot(p)


TABLES = ("scaling", "scaling_wall", "scaling_fit")
"""The result tables of the study, each ``<name>.csv``."""


def replot(folders: Folders) -> int:
    """``--replot``: the figure from the study's tables in --results-dir."""
    names = [f"{name}.csv" for name in TABLES]
    tables = dict(zip(TABLES, read_for_replot(folders, *names)))
    figures, sources = replot_figures(folders, *names)
    plot(tables, figures / "scaling", sources)
    print(f"wrote {figures / 'scaling'}.png/.pdf")
    return 0


def configure(args: argparse.Namespace) -> Command[ScalingConfig]:
    given = given_fields(args, ScalingConfig)
    if given.get("n_agents"):
        given["n_agents"] = tuple(sorted(given["n_agents"]))  # the fits read them in order
    return Command.of(args, for_scale(ScalingConfig, args.scale, **given))


def run(cmd: Command[ScalingConfig], folders: Folders) -> int:
    cfg, scale, seed = cmd.study, folders.scale, cmd.seed
    if cmd.replot:
        return replot(folders)
    check_work(cfg)
    figures = folders.open_figures() if cmd.figure else None
    results = folders.open_results()
    warm_up()
    t0 = time.perf_counter()
    tables = run_study(cfg, seed)
    wall = time.perf_counter() - t0
    for name, frame in tables.items():
        prov = provenance(cfg, command="scaling", scale=scale, seed=seed,
                          wall_seconds=wall)
        write_result(results / f"{name}.csv", frame, prov)
    if figures is not None:
        plot(tables, figures / "scaling", [results / f"{name}.csv" for name in tables])
    print(tables["scaling_fit"].to_string(index=False))
    return 0
