"""Claim X1, beyond the paper: does M-GAE matter? (docs/semantics.md section 6.9)

PS-TRPO is trained with each advantage estimator of ``repro.learn.m_gae.ESTIMATORS``, everything
else equal: M-GAE (the paper's), decision-step GAE (every macro-action one step, one discount
matched to the batch's mean macro-action duration: what a user of a standard library would do) and
duration-discounted GAE with a lambda per decision (which separates M-GAE's discount from its
lambda part).

- **Bus**: the lambda sweep's lambda = 2 setting (540 episodes per epoch, its epochs and seeds at
  the same scale, ``repro.studies.bus.sweeps``); a run's score is its final return as in C1, the
  mean average return of its last ``final_epochs`` epochs.
- **Wildfire**: the transfer study's ED training (its sizes at the same scale,
  ``repro.studies.transfer.study``); a run's score is its final policy's ADR on the study's ED
  test episodes.

The M-GAE runs are those studies' own runs (the same TrainConfig, environment and seeds, in the same
run folders), so each is trained once for both; the other estimators' runs sit beside them, named
after them with the estimator appended. The wildfire's M-GAE policies are tested first, so that
they get the sampling streams they have in the transfer study: their ADRs equal transfer.csv's ED
rows. At lam = 1, the wildfire's, duration-discounted GAE is M-GAE exactly (lambda_d = 1), so it is
not trained again there.

Outputs: ``results/beyond_mgae.csv`` (one row per run), ``beyond_mgae_summary.csv`` (per environment
and estimator: mean, standard error, IQM, 95% bootstrap CI of the mean, and where M-GAE's CI lies
against it), ``figures/beyond_mgae.png/.pdf``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pandas as pd

from repro.core.config import Validated, for_scale, from_recorded, given_fields
from repro.envs.bus import BusConfig
from repro.learn.config import (DEFAULT_LEARNER, LEARNERS, add_learner_option, learner_label,
                                learner_stem)
from repro.learn.m_gae import ESTIMATORS
from repro.runs.provenance import provenance
from repro.runs.results import save_figure, write_result
from repro.runs.stats import bootstrap_ci, ci_side, iqm, sem
from repro.studies.bus import sweeps as bus_sweeps
from repro.studies.kit.options import Command, Folders, add_replot, replot_pair
from repro.studies.kit.sweep import (TrainJob, add_study_arguments, run_dir, run_sweep,
                                    run_sweeps)
from repro.studies.transfer import study as transfer

REFERENCE = "m-gae"
"""The estimator the others are compared with: the paper's."""
_BOOT_STREAM = 3
"""Child stream of the root seed for the bootstrap (0-2 are the transfer study's test streams)."""


@dataclass(frozen=True)
class MgaeStudyConfig(Validated):
    """What X1 compares. The sizes are the bus lambda sweep's and the transfer study's at the same
    scale, so that the M-GAE runs are theirs."""

    learner: str = DEFAULT_LEARNER
    """The named learner of every run (``repro.learn.config.LEARNERS``), with the sizes the two
    studies give it."""
    estimators: tuple[str, ...] = tuple(ESTIMATORS)
    """Advantage estimators trained (``repro.learn.m_gae.ESTIMATORS``); M-GAE first, the others
    are compared with it."""
    seeds: int | None = None
    """Policies per estimator and environment; None: the studies' (paper scale: 5)."""
    n_boot: int = 2000
    """Bootstrap replicates of each CI."""

    SCALES: ClassVar[dict] = {"smoke": dict(n_boot=200), "quick": {}, "paper": {}}

    def validate(self) -> None:
        self.check(len(self.estimators) >= 2 and self.estimators[0] == REFERENCE
                and set(self.estimators) <= set(ESTIMATORS), "estimators",
                   f"{REFERENCE} and one or more of " + ", ".join(ESTIMATORS))
        self.check(self.learner in LEARNERS, "learner", "one of " + ", ".join(LEARNERS))
        self.check(self.seeds is None or self.seeds >= 1, "seeds", "an integer >= 1")
        self.check(self.n_boot >= 1, "n_boot", "an integer >= 1")

    def bus(self, scale: str) -> bus_sweeps.BusSweepConfig:
        """The bus lambda sweep at ``scale``."""
        return bus_sweeps.sweep_config(scale, self.learner, seeds=self.seeds)

    def wildfire(self, scale: str) -> transfer.TransferConfig:
        """The transfer study at ``scale``, ED only."""
        return for_scale(transfer.TransferConfig, scale, seeds=self.seeds, only=("ED",),
                         learner=self.learner)

    @property
    def stem(self) -> str:
        """File stem of the results and the figure: beyond_mgae, then _suite for the suite's
        learner."""
        return learner_stem("beyond_mgae", self.learner)


def with_estimator(job: TrainJob, estimator: str) -> TrainJob:
    """``job`` trained with ``estimator``: M-GAE keeps the job (its study's run); another estimator
    gets a run of its own beside it."""
    if estimator == REFERENCE:
        return job
    return TrainJob(f"{job.name}-{estimator}",
                    dataclasses.replace(job.train, advantage=estimator), job.env_config)


def is_m_gae(estimator: str, lam: float) -> bool:
    """Whether ``estimator`` computes exactly M-GAE's advantages at ``lam``: duration-gae does at
    lam = 1 (its lambda_d is 1), so it needs no run of its own there."""
    return estimator == REFERENCE or (estimator == "duration-gae" and lam == 1.0)


def estimator_jobs(cfg: MgaeStudyConfig, base: list[TrainJob]) -> list[tuple[str, TrainJob]]:
    """(estimator, job) for every estimator and job of ``base`` (the study's M-GAE jobs), the M-GAE
    jobs first."""
    return [(e, with_estimator(job, e)) for e in cfg.estimators for job in base
            if e == REFERENCE or not is_m_gae(e, job.train.lam)]


def bus_jobs(cmd: Command[MgaeStudyConfig], folders: Folders) -> tuple[
        list[tuple[str, TrainJob]], Path]:
    """The bus runs, labelled by estimator, and the folder of their run folders."""
    sweep = cmd.study.bus(folders.scale)
    bus = BusConfig()
    base = [j for j in bus_sweeps.jobs(sweep, "lambda", cmd.seed, bus)
            if j.train.lam == sweep.batch_lambda]  # the paper's bus lambda, 2
    return estimator_jobs(cmd.study, base), folders.run_root(bus_sweeps.runs_folder(bus))


def wildfire_jobs(cmd: Command[MgaeStudyConfig], folders: Folders) -> list[tuple[str, TrainJob]]:
    """The wildfire runs, labelled by estimator (in the transfer study's run folders)."""
    study = cmd.study.wildfire(folders.scale)
    return estimator_jobs(cmd.study, [job for _, job in transfer.make_jobs(study, folders.scale,
                                                                          cmd.seed)])


def bus_runs(cmd: Command[MgaeStudyConfig], folders: Folders) -> pd.DataFrame:
    """Train (or resume) the bus runs; one row per run with its final return."""
    sweep = cmd.study.bus(folders.scale)
    labelled, root = bus_jobs(cmd, folders)
    run_sweep([job for _, job in labelled], root, cmd.workers)
    rows = []
    for estimator, job in labelled:
        final = bus_sweeps.final_returns(sweep, bus_sweeps.curves(sweep, [job], root))
        rows.append(dict(env="bus", estimator=estimator, lam=job.train.lam,
                         seed=job.train.seed, epochs=sweep.epochs,
                         batch_episodes=job.train.batch_episodes,
                         score=float(final.final_return.iloc[0]), run=str(run_dir(root, job))))
    return pd.DataFrame(rows)


def wildfire_runs(cmd: Command[MgaeStudyConfig], folders: Folders) -> pd.DataFrame:
    """Train (or resume) the wildfire runs and test them on ED; one row per run with its ADR."""
    study = cmd.study.wildfire(folders.scale)
    labelled = wildfire_jobs(cmd, folders)
    tested, sweep = transfer.train_and_test(study, folders, labelled, cmd.seed, cmd.workers)
    return pd.DataFrame(dict(env="wildfire", estimator=tested.simulator,
                             lam=[job.train.lam for _, job in labelled],
                             seed=tested.train_seed, epochs=tested.epochs,
                             batch_episodes=tested.batch_episodes, score=tested.adr_ed,
                             run=[str(Path(sweep["runs_dir"]) / name) for name in tested.run]))


def summarise(runs: pd.DataFrame, n_boot: int, seed: int) -> pd.DataFrame:
    """Per environment and estimator: mean, SEM, IQM and a bootstrap CI of the mean over runs, and
    where M-GAE's CI lies against it (``mgae_ci``: above, below or overlapping; empty for M-GAE)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_BOOT_STREAM,)))
    rows = []
    for (env, estimator), grp in runs.groupby(["env", "estimator"], sort=False):
        x = grp.score.to_numpy()
        _, lo, hi = bootstrap_ci(x, np.mean, n_boot=n_boot, rng=rng)
        rows.append(dict(env=env, estimator=estimator, lam=grp.lam.iloc[0], n_runs=len(x),
                         mean=float(x.mean()), sem=sem(x), iqm=float(iqm(x)), ci_low=lo,
                         ci_high=hi))
    table = pd.DataFrame(rows)
    ref = table[table.estimator == REFERENCE].set_index("env")
    table["mgae_ci"] = [
        "" if r.estimator == REFERENCE else ci_side(ref.loc[r.env], r) for r in table.itertuples()]
    return table


def plot(runs: pd.DataFrame, summary: pd.DataFrame, stem: Path, title: str,
         sources: list[Path]) -> None:
    """One panel per environment: each run's score (dots) and the mean with its 95% CI per
    estimator; ``sources``: the runs' and the summary's CSVs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    envs = list(dict.fromkeys(summary.env))
    labels = {"bus": "final return (mean of the last epochs)", "wildfire": "ADR on ED"}
    labels = {env: f"{label}\nmean over runs, error bars: 95% bootstrap CI"
              for env, label in labels.items()}
    fig, axes = plt.subplots(1, len(envs), figsize=(4.2 * len(envs), 4), squeeze=False)
    for ax, env in zip(axes[0], envs):
        s = summary[summary.env == env].reset_index(drop=True)
        for i, row in s.iterrows():
            dots = runs[(runs.env == env) & (runs.estimator == row.estimator)].score
            ax.plot(np.full(len(dots), i - 0.12), dots, ".", color=f"C{i}", alpha=0.5, ms=5)
            ax.errorbar([i + 0.06], [row["mean"]], yerr=[[row["mean"] - row.ci_low],
                                                        [row.ci_high - row["mean"]]],
                        fmt="o", color=f"C{i}", capsize=4)
        ax.set_xticks(range(len(s)), s.estimator)
        ax.set_xlim(-0.6, len(s) - 0.4)
        same = [e for e in dict.fromkeys(summary.estimator) if e not in set(s.estimator)]
        note = "".join(f"; {e} = m-gae here" for e in same)
        ax.set_title(f"{env} (lambda = {s.lam.iloc[0]:g}{note})", fontsize=9)
        ax.set_ylabel(labels[env])
        ax.grid(True, alpha=0.3)
    fig.suptitle(title, fontsize=9)
    save_figure(fig, stem, sources)


def title(cfg: MgaeStudyConfig, scale: str) -> str:
    """The figure's title: the learner and both studies' sizes at ``scale``."""
    bus, wildfire = cfg.bus(scale), cfg.wildfire(scale)
    return (f"X1: advantage estimators, everything else equal, {learner_label(cfg.learner)}; "
            f"{scale} scale: bus {bus.seeds} x {bus.epochs} epochs x {bus.lambda_batch} "
            f"{bus.unit.removeprefix('batch_')}, wildfire {wildfire.seeds} x {wildfire.epochs} x "
            f"{transfer.batch_label(wildfire)} (ED)")


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_study_arguments(p, MgaeStudyConfig)
    add_learner_option(p, "beyond_mgae_suite*")
    add_replot(p)


def replot(cfg: MgaeStudyConfig, folders: Folders) -> int:
    """``--replot``: the figure of ``cfg``'s learner from its CSVs, titled with the settings their
    sidecar records."""
    return replot_pair(folders, cfg.stem, plot=plot, title=lambda prov: title(
        from_recorded(MgaeStudyConfig, prov["config"]["study"]), prov["scale"]))


def configure(args: argparse.Namespace) -> Command[MgaeStudyConfig]:
    return Command.of(args, for_scale(MgaeStudyConfig, args.scale, learner=args.learner,
                                      **given_fields(args, MgaeStudyConfig, ("seeds",))))


def run(cmd: Command[MgaeStudyConfig], folders: Folders) -> int:
    cfg, scale, seed = cmd.study, folders.scale, cmd.seed
    if cmd.replot:
        return replot(cfg, folders)
    results, figures = folders.open()
    t0 = time.perf_counter()
    bus_labelled, bus_root = bus_jobs(cmd, folders)
    wildfire_root = transfer.runs_folder(folders, cfg.wildfire(scale))
    run_sweeps([([job for _, job in bus_labelled], bus_root),  # both environments' in one pool
                ([job for _, job in wildfire_jobs(cmd, folders)], wildfire_root)], cmd.workers)
    runs = pd.concat([bus_runs(cmd, folders), wildfire_runs(cmd, folders)],
                     ignore_index=True)
    summary = summarise(runs, cfg.n_boot, seed)
    bus, wildfire = cfg.bus(scale), cfg.wildfire(scale)
    prov = provenance(dict(study=dataclasses.asdict(cfg), bus=dataclasses.asdict(bus),
                           wildfire=dataclasses.asdict(wildfire)),
                      command="beyond-mgae", scale=scale, seed=seed,
                      wall_seconds=time.perf_counter() - t0)
    sources = [write_result(results / f"{cfg.stem}.csv", runs, prov),
               write_result(results / f"{cfg.stem}_summary.csv", summary, prov)]
    plot(runs, summary, figures / cfg.stem, title(cfg, scale), sources)
    print(summary.to_string(index=False))
    return 0
