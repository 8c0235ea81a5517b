"""Race conditions in the wildfire simulator itself, and dT against N (claim X2, beyond the paper;
docs/semantics.md sections 3.12 and 6.10).

C10 counts races among N i.i.d. event times. This driver counts them in FS-dT wildfire episodes:
N UAVs and N clusters of three fires (``n_clusters``; N = 3 is the paper's layout), under the
nearest-fire and the random heuristics, on a log grid of dT. A race is an instant at which timeouts
of different exact (unrounded) due times expire: FS put together what ED, on the same draws and
actions, separates. The fast engine counts them in the FS run itself (``count_races``).

Per (policy, N, dT): the probability that an episode contains a race, with its Clopper-Pearson 95%
interval, and the races per decision. Every dT of a (policy, N) plays the same episode draws with
the same policy stream. Per (policy, N): dT*, where P(race) first reaches delta, interpolated
linearly in log dT between the two grid points around it; per policy: OLS (statsmodels) of
log dT* = log alpha - beta log N, set beside C10's beta (``table_race.csv`` of the same results
folder, when there).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pandas as pd

from repro.core.config import Validated, add_config_arguments, for_scale, given_fields
from repro.envs.wildfire import WildfireConfig, make_env
from repro.envs.wildfire.policies import POLICIES
from repro.runs.provenance import provenance
from repro.runs.results import read_result, save_figure, write_result
from repro.studies.kit.options import (Command, Folders, add_common, add_replot, read_for_replot,
                                       replot_figures)
from repro.studies.kit.sweep import map_tasks
from repro.studies.races.study import FIT, RACES, fit_power_law
from repro.studies.wildfire.study import evaluate

MIN_FIT_POINTS = 3
"""Crossings an OLS fit needs for a standard error of its slope."""
MAX_GRID = 10_000
"""The most steps of the dT grid (the paper scale's has 56)."""
_ENV_STREAM, _POLICY_STREAM = 0, 1


@dataclass(frozen=True)
class BeyondRacesConfig(Validated):
    """Settings of the race study in the wildfire simulator; the semantics are the defaults
    (released) at every scale, with n_clusters = N."""

    episodes: int = 200
    """FS episodes per (policy, N, dT) cell."""
    n_agents: tuple[int, ...] = (3, 6, 12, 24)
    """Numbers of UAVs N, each with N clusters of three fires."""
    policies: tuple[str, ...] = ("nearest", "random")
    """Heuristic policies (``repro.envs.wildfire.policies``)."""
    log10_dt_min: float = -6.0
    """Smallest dT of the grid, 10^x s (P(race) is below 1% there for N <= 24)."""
    log10_dt_max: float = 1.0
    """Largest dT, 10^x s (every episode races there)."""
    log10_dt_step: float = 0.125
    """Spacing of the grid in decades."""
    delta: float = 0.1
    """The race probability per episode that dT* keeps below (C10's)."""

    ALIASES: ClassVar[dict[str, str]] = {"policy": "policies"}
    """``--policy nearest --policy random``, the older flag, still taken."""

    SCALES: ClassVar[dict] = {
        "smoke": dict(episodes=20, n_agents=(3, 6), log10_dt_step=0.5),
        "quick": {},
        "paper": dict(episodes=2000),
    }

    def validate(self) -> None:
        self.check(self.episodes >= 1, "episodes", "an integer >= 1")
        self.check(len(set(self.n_agents)) >= 2 and min(self.n_agents) >= 1, "n_agents",
                   "at least two different integers >= 1")
        self.check(set(self.policies) <= set(POLICIES) and len(self.policies) >= 1, "policies",
                   "one of " + ", ".join(POLICIES))
        # ten times the race count's tolerance (1 ns) at least
        self.check(-8 <= self.log10_dt_min <= 2, "log10_dt_min", "in [-8, 2] (dT from 10 ns)")
        self.check(self.log10_dt_min < self.log10_dt_max <= 2, "log10_dt_max",
                   "above --log10-dt-min and at most 2 (dT to 100 s)")
        span = self.log10_dt_max - self.log10_dt_min
        self.check(span / MAX_GRID <= self.log10_dt_step <= span, "log10_dt_step",
                   f"a number in [{span / MAX_GRID:g}, {span:g}] (--log10-dt-max minus "
                   f"--log10-dt-min, in at most {MAX_GRID:,} steps)")
        self.check(0 < self.delta < 1, "delta", "in (0, 1)")

    def log10_dts(self) -> np.ndarray:
        """The grid, smallest first, in decades (rounded, so that 10^x prints as written)."""
        n = int(np.floor((self.log10_dt_max - self.log10_dt_min) / self.log10_dt_step + 1e-9))
        return np.round(self.log10_dt_min + self.log10_dt_step * np.arange(n + 1), 9)


def cell(policy: str, n: int, log10_dt: float, episodes: int, seed: int) -> dict:
    """One (policy, N, dT) cell: ``episodes`` FS episodes with the race count on. The episode
    draws and the policy's stream depend on (policy, N) and the seed only, not on dT."""
    key = (list(POLICIES).index(policy), n)
    env_seed = int(np.random.SeedSequence(seed, spawn_key=(*key, _ENV_STREAM)).generate_state(1)[0])
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(*key, _POLICY_STREAM)))
    env = make_env(WildfireConfig(n_agents=n, n_clusters=n, dt=10.0 ** log10_dt),
                   count_races=True)
    races: list[np.ndarray] = []
    rollout = evaluate(env, POLICIES[policy](rng), episodes, env_seed, keep_obs=False,
                       on_batch=lambda batch: races.append(batch.info["races"]))
    per_episode = np.concatenate(races)
    raced = int((per_episode > 0).sum())
    low, high = proportion_ci(raced, episodes)
    return dict(policy=policy, n_agents=n, n_clusters=n, log10_dt=log10_dt, dt=10.0 ** log10_dt,
                episodes=episodes, decisions=rollout.n_decisions, races=int(per_episode.sum()),
                raced_episodes=raced, p_race_episode=raced / episodes, p_race_ci_low=low,
                p_race_ci_high=high, races_per_decision=per_episode.sum() / rollout.n_decisions,
                truncated_episodes=rollout.n_truncated)


def proportion_ci(k: int, n: int) -> tuple[float, float]:
    """Clopper-Pearson 95% interval of a proportion k / n (exact; sensible at 0 and 1)."""
    from statsmodels.stats.proportion import proportion_confint

    low, high = proportion_confint(k, n, alpha=0.05, method="beta")
    return float(low), float(high)


def crossing(log10_dt: np.ndarray, p: np.ndarray, delta: float) -> float:
    """log10 dT at which ``p`` (on the grid ``log10_dt``, increasing) first reaches ``delta``,
    linear in log dT between the grid points around it: the largest dT whose race probability,
    read along the grid from below, stays under delta. NaN if the grid does not bracket it."""
    above = np.flatnonzero(p >= delta)
    if len(above) == 0 or above[0] == 0:
        return float("nan")
    k = above[0]
    return float(log10_dt[k - 1] + (delta - p[k - 1]) / (p[k] - p[k - 1])
                 * (log10_dt[k] - log10_dt[k - 1]))


def fit(table: pd.DataFrame, delta: float, c10_beta: float) -> pd.DataFrame:
    """Per (policy, N): dT*; per policy: alpha, beta and beta's standard error of the log-log OLS
    over the N whose crossing the grid brackets (NaN with fewer than MIN_FIT_POINTS)."""
    rows = []
    for policy, grp in table.groupby("policy", sort=False):
        stars = {int(n): crossing(g.log10_dt.to_numpy(), g.p_race_episode.to_numpy(), delta)
                 for n, g in grp.sort_values("log10_dt").groupby("n_agents")}
        ok = [n for n, x in stars.items() if np.isfinite(x)]
        beta = se = alpha = float("nan")
        if len(ok) >= MIN_FIT_POINTS:
            beta, se, alpha = fit_power_law(np.array(ok), 10.0 ** np.array([stars[n] for n in ok]))
        rows += [dict(policy=policy, n_agents=n, dt_star=10.0 ** x, delta=delta, alpha=alpha,
                      beta=beta, beta_se=se, n_fit=len(ok), c10_beta=c10_beta)
                 for n, x in stars.items()]
    return pd.DataFrame(rows)


def c10_beta(results: Path) -> float:
    """C10's exponent, the mean over its distributions in ``table_race.csv``; NaN if not run."""
    try:
        return float(read_result(results / "table_race.csv").beta.mean())
    except FileNotFoundError:
        return float("nan")


def plot(table: pd.DataFrame, fits: pd.DataFrame, stem: Path, sources: list[Path]) -> None:
    """Left: P(race per episode) against dT per N and policy; right: dT* against N, log-log, with
    each policy's fit and lines of C10's slope through the fits' middle; ``sources``: the table's
    and the fits' CSVs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    styles = dict(zip(table.policy.unique(), ("-", "--", ":")))
    markers = dict(zip(table.policy.unique(), ("o", "s", "^")))
    colors = {n: f"C{i}" for i, n in enumerate(sorted(table.n_agents.unique()))}
    for (policy, n), g in table.groupby(["policy", "n_agents"], sort=False):
        ax.semilogx(g.dt, g.p_race_episode, styles[policy], color=colors[n], lw=1.2,
                    label=f"{policy}, N = {n}")
    ax.axhline(fits.delta.iloc[0], color="k", lw=0.8, ls=":")
    ax.set_xlabel(r"$\Delta T$ (s)")
    ax.set_ylabel("P(race in an episode)")
    ax.legend(fontsize=6, ncol=2)
    ax.grid(True, which="both", alpha=0.3)
    c10 = fits.c10_beta.iloc[0]
    for policy, g in fits.groupby("policy", sort=False):
        g = g[np.isfinite(g.dt_star)]
        ax2.loglog(g.n_agents, g.dt_star, markers[policy], color="k", mfc="none",
                   label=f"{policy}: $\\beta$ = {g.beta.iloc[0]:.2f} ({g.beta_se.iloc[0]:.2f})"
                   if len(g) else policy)
        if len(g) and np.isfinite(g.beta.iloc[0]):
            n = np.geomspace(g.n_agents.min(), g.n_agents.max(), 20)
            ax2.loglog(n, g.alpha.iloc[0] * n ** -g.beta.iloc[0], styles[policy], color="k",
                       lw=1)
            if np.isfinite(c10):
                mid = np.sqrt(n[0] * n[-1])
                at = g.alpha.iloc[0] * mid ** -g.beta.iloc[0]
                ax2.loglog(n, at * (n / mid) ** -c10, styles[policy], color="C3", lw=0.8)
    if np.isfinite(c10):
        ax2.plot([], [], color="C3", lw=0.8, label=f"C10's slope, $\\beta$ = {c10:.2f}")
    ax2.set_xlabel("Number of UAVs $N$ (= clusters)")
    ax2.set_ylabel(rf"$\Delta T^*$: P(race) = {fits.delta.iloc[0]:g}")
    ax2.legend(fontsize=7)
    ax2.grid(True, which="both", alpha=0.3)
    save_figure(fig, stem, sources)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p)
    add_config_arguments(p, BeyondRacesConfig)
    p.add_argument("--n-jobs", type=int, help="worker processes (default: all cores)")
    add_replot(p)


def replot(folders: Folders) -> int:
    """``--replot``: the figure from the race table and its fits in --results-dir."""
    names = [f"{RACES}.csv", f"{FIT}.csv"]
    table, fits = read_for_replot(folders, *names)
    figures, sources = replot_figures(folders, *names)
    plot(table, fits, figures / RACES, sources)
    print(f"wrote {figures / RACES}.png/.pdf")
    return 0


def configure(args: argparse.Namespace) -> Command[BeyondRacesConfig]:
    return Command.of(args, for_scale(BeyondRacesConfig, args.scale,
                                      **given_fields(args, BeyondRacesConfig)))


def run(cmd: Command[BeyondRacesConfig], folders: Folders) -> int:
    cfg, scale, seed = cmd.study, folders.scale, cmd.seed
    if cmd.replot:
        return replot(folders)
    figures = folders.open_figures()
    results = folders.open_results()
    t0 = time.perf_counter()
    # largest N first: the longest cells start first, so the workers finish together
    tasks = [(policy, n, float(x), cfg.episodes, seed) for n in sorted(cfg.n_agents)[::-1]
             for policy in cfg.policies for x in cfg.log10_dts()]
    table = pd.DataFrame(map_tasks(cell, tasks, cmd.workers))
    table = table.sort_values(["policy", "n_agents", "log10_dt"], kind="stable",
                              key=lambda c: c.map(cfg.policies.index) if c.name == "policy"
                              else c).reset_index(drop=True)
    fits = fit(table, cfg.delta, c10_beta(results))
    prov = provenance(cfg, command="beyond-races", scale=scale, seed=seed,
                      wall_seconds=time.perf_counter() - t0)
    sources = [write_result(results / f"{RACES}.csv", table, prov),
               write_result(results / f"{FIT}.csv", fits, prov)]
    plot(table, fits, figures / RACES, sources)
    print(fits.to_string(index=False))
    return 0
