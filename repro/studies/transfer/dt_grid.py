"""Claim X3, beyond the paper: transfer to ED against dT, with the race rate beside it
(docs/semantics.md section 6.11).

The transfer study (``repro.studies.transfer.study``, C8) on a fine grid: policies trained on ED
and on FS-dT for dT = 10^(-2 + 0.25 k) s, k = 0..12, are tested on ED. The grid contains the study's
five dT, and the runs the two share are the same runs (same run identity and seed streams, in the
same run folders), so either study trains only what the other has not. The study's own simulators
are tested first, so that their policies get the sampling streams they have there: their rows
equal transfer.csv's.

Beside the ADR the figure draws the race rate that claim X2 measures in the wildfire simulator,
``races.csv`` in the results folder (its rows with the study's N = 3 UAVs: races per decision
against dT), when that file exists; otherwise it draws the ADR alone and says so.

Outputs: ``results/transfer_dt_grid.csv`` (per policy, transfer.csv's columns) and
``transfer_dt_grid_summary.csv`` (per training simulator, ED first with dt = 0, then ascending dT),
``figures/transfer_dt_grid.png/.pdf``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import pandas as pd

from repro.core.config import Validated, for_scale, from_recorded, given_fields
from repro.learn.config import (DEFAULT_LEARNER, LEARNERS, add_learner_option, learner_label,
                                learner_stem)
from repro.runs.provenance import provenance
from repro.runs.results import read_provenance, read_result, save_figure, write_result
from repro.studies.kit.options import Command, Folders, add_replot, read_for_replot, replot_figures
from repro.studies.kit.sweep import add_study_arguments
from repro.studies.races import study as races
from repro.studies.transfer import study as transfer

RACES = f"{races.RACES}.csv"
"""Claim X2's result (``beyond-races``): at least the columns policy, n_agents, dt,
p_race_episode and races_per_decision."""
RACE_POLICIES = {"nearest": "-", "random": "--"}
"""The policies of races.csv drawn, with their line styles."""


@dataclass(frozen=True)
class TransferDtConfig(Validated):
    """The dT grid of X3; the sizes are the transfer study's at the same scale, so that the runs
    the two share are the same runs."""

    log10_dts: tuple[float, ...] = tuple(-2.0 + 0.25 * k for k in range(13))
    """FS training simulators: dT = 10^x s, a log grid from 0.01 to 10 s, a quarter decade apart
    (exact binary fractions, so the study's five dT are the very same numbers)."""
    seeds: int | None = None
    """Policies per training simulator; None: the transfer study's (paper scale: 5)."""
    learner: str = DEFAULT_LEARNER
    """The named learner of every policy (``repro.learn.config.LEARNERS``)."""
    race_agents: int = 3
    """The rows of races.csv drawn beside the ADR: those of N UAVs, the study's."""

    SCALES: ClassVar[dict] = {"smoke": {}, "quick": {}, "paper": {}}

    def validate(self) -> None:
        distinct = len(set(self.log10_dts)) == len(self.log10_dts)
        self.check(len(self.log10_dts) >= 1 and distinct, "log10_dts",
                   "one or more distinct exponents")
        self.check(self.seeds is None or self.seeds >= 1, "seeds", "an integer >= 1")
        self.check(self.learner in LEARNERS, "learner", "one of " + ", ".join(LEARNERS))
        self.check(self.race_agents >= 2, "race_agents", "an integer >= 2")

    def study(self, scale: str) -> transfer.TransferConfig:
        """The transfer study at ``scale`` on this grid, without its T_health variant. The study's
        own dT come first: a policy's test sampling stream is its place among those tested."""
        own = transfer.TransferConfig().log10_dts
        dts = (*(x for x in own if x in self.log10_dts),
               *(x for x in self.log10_dts if x not in own))
        labels = ("ED", *(transfer.fs_label(10.0 ** x) for x in dts))
        return for_scale(transfer.TransferConfig, scale, seeds=self.seeds, log10_dts=dts,
                         only=labels, learner=self.learner)

    @property
    def stem(self) -> str:
        """File stem of the results and the figure: transfer_dt_grid, then _suite for the suite's
        learner."""
        return learner_stem("transfer_dt_grid", self.learner)


def read_races(results: Path, n_agents: int) -> pd.DataFrame | None:
    """X2's race rates of ``n_agents`` UAVs, by policy and ascending dT (None if not yet run)."""
    try:
        races = read_result(results / RACES)
    except FileNotFoundError:
        return None
    return races[(races.n_agents == n_agents) & (races.dt > 0)].sort_values(["policy", "dt"])


def by_dt(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` in ascending dT, ED (dt = 0) first; the order of a policy's rows is kept."""
    return frame.sort_values("dt", kind="stable").reset_index(drop=True)


def plot(per_policy: pd.DataFrame, summary: pd.DataFrame, races: pd.DataFrame | None,
         n_agents: int, stem: Path, title: str, sources: list[Path]) -> None:
    """ADR on ED (mean and 95% CI per FS-dT, each policy a dot) against dT on a log axis, the
    ED-trained policies' CI as a band; on a second axis the race rate, when X2 has measured it.
    ``sources``: the CSVs drawn (the race rate's too, where drawn)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ed, fs = summary[summary.dt == 0].iloc[0], summary[summary.dt > 0]
    fig, ax = plt.subplots(figsize=(7.5, 4.4))
    ax.axhspan(ed.ci_low, ed.ci_high, color="0.6", alpha=0.3, label="trained on ED (95% CI)")
    ax.axhline(ed["mean"], color="0.4", lw=1)
    dots = per_policy[per_policy.dt > 0]
    ax.plot(dots.dt, dots.adr_ed, ".", color="C0", alpha=0.35, ms=4)
    ax.errorbar(fs.dt, fs["mean"], yerr=[fs["mean"] - fs.ci_low, fs.ci_high - fs["mean"]],
                fmt="o-", color="C0", capsize=3, label="trained on FS-dT (mean, 95% CI)")
    ax.set_xscale("log")
    ax.set_xlabel("training step dT (s)")
    ax.set_ylabel("ADR on ED (T_health = 3.0)")
    ax.grid(True, which="both", alpha=0.3)
    handles, names = ax.get_legend_handles_labels()
    if races is None:
        ax.set_title(f"{title}\nrace rate: not yet measured ({RACES} missing, claim X2)",
                     fontsize=8)
    else:
        ax.set_title(title, fontsize=8)
        twin = ax.twinx()
        for policy, style in RACE_POLICIES.items():
            r = races[races.policy == policy]
            twin.plot(r.dt, r.races_per_decision, style, color="C3",
                      label=f"races per decision, {policy} policy (N = {n_agents})")
        twin.set_ylabel("race rate (races per decision)", color="C3")
        twin.set_ylim(bottom=0)
        more, more_names = twin.get_legend_handles_labels()
        handles, names = handles + more, names + more_names
    ax.legend(handles, names, fontsize=7, loc="best")
    save_figure(fig, stem, sources)


def title(study: transfer.TransferConfig, scale: str) -> str:
    """The figure's title: the learner and the sizes of the transfer study on the grid."""
    return (f"X3: transfer to ED against the training step, {learner_label(study.learner)}; "
            f"{scale} scale: {study.seeds} policies x {study.epochs} epochs x "
            f"{transfer.batch_label(study)} per simulator")


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_study_arguments(p, TransferDtConfig)
    add_learner_option(p, "transfer_dt_grid_suite*")
    add_replot(p)


def replot(cfg: TransferDtConfig, folders: Folders) -> int:
    """``--replot``: the figure of ``cfg``'s learner from its CSVs (and X2's race rates where
    they are in --results-dir), titled with the sizes its sidecar records."""
    names = [f"{cfg.stem}.csv", f"{cfg.stem}_summary.csv"]
    per_policy, summary = read_for_replot(folders, *names)
    results = folders.results
    prov = read_provenance(results / names[0])
    races = read_races(results, cfg.race_agents)
    figures, sources = replot_figures(folders, *names, *([] if races is None else [RACES]))
    study = from_recorded(transfer.TransferConfig, prov["config"]["study"])
    plot(per_policy, summary, races, cfg.race_agents, figures / cfg.stem,
         title(study, prov["scale"]), sources)
    print(f"wrote {figures / cfg.stem}.png/.pdf")
    return 0


def configure(args: argparse.Namespace) -> Command[TransferDtConfig]:
    return Command.of(args, for_scale(TransferDtConfig, args.scale, learner=args.learner,
                                      **given_fields(args, TransferDtConfig, ("seeds",))))


def run(cmd: Command[TransferDtConfig], folders: Folders) -> int:
    cfg, scale, seed = cmd.study, folders.scale, cmd.seed
    if cmd.replot:
        return replot(cfg, folders)
    study = cfg.study(scale)
    results, figures = folders.open()
    t0 = time.perf_counter()
    tested, extra = transfer.train_and_test(study, folders, transfer.make_jobs(study, scale, seed),
                                            seed, cmd.workers)
    # summarised in the order tested, so that the shared simulators get the study's CIs too
    summary = by_dt(transfer.summarise(tested, study.n_boot, seed))
    per_policy = by_dt(tested)
    prov = provenance(dict(grid=dataclasses.asdict(cfg), study=dataclasses.asdict(study)),
                      command="beyond-transfer-dt", scale=scale, seed=seed,
                      wall_seconds=time.perf_counter() - t0, extra=extra)
    sources = [write_result(results / f"{cfg.stem}.csv", per_policy, prov),
               write_result(results / f"{cfg.stem}_summary.csv", summary, prov)]
    races = read_races(results, cfg.race_agents)
    plot(per_policy, summary, races, cfg.race_agents, figures / cfg.stem, title(study, scale),
         sources + ([] if races is None else [results / RACES]))
    print(summary[["simulator", "n_policies", "mean", "sem", "ci_low", "ci_high"]]
          .to_string(index=False))
    return 0
