"""The bus training sweeps (paper Figs. bbtraining and bbtest; claims C1-C3): PS-TRPO + M-GAE
training curves over lambda (at 540 episodes per epoch) and over the batch size (at lambda = 2),
with the No Holding and Optimized Thresholds returns as horizontal lines.

Every (lambda, batch, seed) is one checkpointed run under ``<runs-dir>/bus-released/`` for the
released semantics, ``<runs-dir>/bus/`` for the corrected ones, ``<runs-dir>/bus-<switches on>/``
otherwise (see
``repro.studies.kit.sweep``); the two sweeps share the lambda = 2, batch = 540 runs, and re-running
a driver skips what is finished. Outputs, for sweep ``s`` in {lambda, batch}:

- ``results/bus_<s>.csv``: one row per run and epoch (lambda, batch, seed, epoch, average_return,
  average_discounted_return; on the released pool also distinct_episodes);
- ``results/bus_<s>_summary.csv``: per setting the final return (mean of a run's last
  ``final_epochs`` epochs) as IQM with a 95% bootstrap CI over seeds, and the two baselines' returns
  (deterministic: one episode each, so no interval); for the lambda sweep also one row per run
  (``policy = mlp-run``) naming its run folder, from which the figure drivers take the best policy;
- ``results/bus_<s>_convergence.csv``: one row per run, the curve read as the paper reads it
  (convergence over the run, not only its end): ``early_return``, the mean average return of the
  first ``early_epochs`` epochs; ``epochs_to_thresholds``, the first epoch whose average return
  reaches the Optimized Thresholds' (empty if none does); ``final_return`` as above;
- ``figures/bus_<s>.png/.pdf``: mean curve per setting with a 95% t-interval band over seeds; on
  the released pool a second panel with the batch's distinct episodes per epoch.

Samplers (``--sampler``): the paper's bus curves were drawn by the released runner, whose 40
unseeded workers share one random stream (:mod:`repro.learn.pool`); ``released-pool`` trains that
way (files ``bus_<s>_pool*``, run folders ``pool_*``), ``independent`` (the default) gives every
episode its own seeded stream.

Epoch count: the paper gives none. In a pilot run (lambda = 2, 540 episodes per epoch, seed 0,
70 epochs) the average return rose steeply for about 20 epochs and plateaued from about epoch 25
(epoch-to-epoch noise of a few percent, no trend after); ``paper`` scale trains 100 epochs, four
times that, so that slower settings (small lambda) plateau too; ``quick`` trains 30.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pandas as pd

from repro.core.config import Validated, for_scale, from_recorded, given_fields
from repro.envs.bus import BusConfig, add_switch_arguments, config_from_args, make_env
from repro.envs.bus.policies import ThresholdPolicy, no_holding
from repro.learn.config import (LEARNERS, SAMPLERS, add_learner_option, batch_unit,
                                learner_label, learner_stem, train_config)
from repro.runs.provenance import provenance
from repro.runs.results import read_provenance, save_figure, write_result
from repro.runs.stats import bootstrap_ci, iqm
from repro.studies.bus.policies import BUS_VARIANTS, read_thresholds, semantics_folders
from repro.studies.kit.options import (Command, Folders, add_replot, read_for_replot,
                                       replot_figures)
from repro.studies.kit.sweep import TrainJob, add_study_arguments, run_dir, run_sweep

SWEEPS = ("lambda", "batch")


@dataclass(frozen=True)
class BusSweepConfig(Validated):
    """What the two bus sweeps train, and how their final returns are summarised."""

    learner: str = "authors"
    """The named learner of every run (``repro.learn.config.LEARNERS``); it counts the batch
    sizes below in its own unit (authors: decisions, suite: episodes)."""
    lambdas: tuple[float, ...] = (1.0, 2.0, 4.0, 8.0)
    """M-GAE lambdas of the lambda sweep (the released BusBunching/runner.sh's)."""
    lambda_batch: int = 12000
    """Batch size in the lambda sweep (the released runner's 12,000 decisions)."""
    batches: tuple[int, ...] = (120, 1200, 12000)
    """Batch sizes of the batch sweep (paper Fig. bbtest: the released batchsizetests.jl's)."""
    batch_lambda: float = 2.0
    """lambda in the batch sweep (the paper's bus lambda)."""
    seeds: int = 5
    """Training runs per setting (seeds seed, seed + 1, ...)."""
    epochs: int = 500
    """Policy updates per run (the released runner.sh: 500)."""
    final_epochs: int = 10
    """A run's final return is the mean average return of its last final_epochs epochs."""
    sampler: str = "independent"
    """The runs' batch sampler (``repro.learn.config.SAMPLERS``): "independent", every episode its
    own seeded stream; "released-pool", the released runner's 40 unseeded workers forked from one
    random state, as the paper's curves were drawn (needs a batch counted in decisions)."""
    early_epochs: int = 100
    """A run's early return is the mean average return of its first early_epochs epochs (all of
    them in a shorter run): how fast it converges, as the paper reads its curves."""
    fvp_subsample: float | None = None
    """Fraction of decisions for TRPO's Fisher-vector products; None: the learner's."""
    n_boot: int = 2000
    """Bootstrap replicates of the confidence intervals."""

    SCALES: ClassVar[dict[str, dict[str, Any]]] = {
        # smoke shrinks the batch sizes too, so that a whole sweep runs in seconds in the tests
        "smoke": dict(lambda_batch=24, batches=(6, 12, 24), seeds=2, epochs=4, final_epochs=2,
                      n_boot=200),
        "quick": dict(seeds=3, epochs=30, final_epochs=5),
        "paper": {},
    }
    SUITE: ClassVar[dict[str, Any]] = dict(lambdas=(0.5, 1.0, 2.0, 4.0), lambda_batch=540,
                                           batches=(54, 135, 270, 540), epochs=100,
                                           fvp_subsample=0.1)
    """The suite learner's sweeps: the paper's 540 episodes per epoch and fractions of it, 100
    epochs (its curves plateau from about epoch 25), a tenth of the decisions for the Fisher
    products (at 540 episodes, ~1.1e5 decisions, the full products took ~75% of an epoch)."""

    def validate(self) -> None:
        self.check(len(self.lambdas) >= 1 and min(self.lambdas) >= 0, "lambdas", ">= 0")
        self.check(len(self.batches) >= 1 and min(self.batches) >= 1, "batches", ">= 1")
        self.check(self.learner in LEARNERS, "learner", "one of " + ", ".join(LEARNERS))
        self.check(self.seeds >= 1, "seeds", "an integer >= 1")
        self.check(self.epochs >= 1, "epochs", "an integer >= 1")
        self.check(1 <= self.final_epochs <= self.epochs, "final_epochs", "in [1, epochs]")
        self.check(self.early_epochs >= 1, "early_epochs", "an integer >= 1")
        self.check(self.sampler in SAMPLERS, "sampler", "one of " + ", ".join(SAMPLERS))
        self.check(not self.pool or self.unit == "batch_decisions", "sampler",
                   "independent for a learner that counts its batch in episodes")

    def settings(self, sweep: str) -> list[tuple[float, int]]:
        """(lambda, batch) of every setting of ``sweep``, in plotting order."""
        if sweep == "lambda":
            return [(lam, self.lambda_batch) for lam in self.lambdas]
        return [(self.batch_lambda, b) for b in self.batches]


    @property
    def pool(self) -> bool:
        """Whether the runs sample with the released pool."""
        return self.sampler == "released-pool"

    @property
    def unit(self) -> str:
        """The TrainConfig field the batch sizes fill: batch_decisions or batch_episodes."""
        return batch_unit(LEARNERS[self.learner])

    def stem(self, sweep: str) -> str:
        """File stem of a sweep's results: bus_<sweep>, then _suite for the suite's learner and
        _pool for the released pool."""
        return learner_stem(f"bus_{sweep}", self.learner) + ("_pool" if self.pool else "")


def sweep_config(scale: str, learner: str | None = None, **overrides: Any) -> BusSweepConfig:
    """The sweeps at ``scale`` for ``learner``: its sizes, then the scale's, then ``overrides``
    (None: not given)."""
    scaled = BusSweepConfig.SCALES.get(scale, {})
    sizes = ({k: v for k, v in BusSweepConfig.SUITE.items() if k not in scaled}
             if learner == "suite" else {})
    given = {k: v for k, v in overrides.items() if v is not None}
    return for_scale(BusSweepConfig, scale, learner=learner, **{**sizes, **given})


def runs_folder(bus: BusConfig) -> str:
    """The folder, under ``--runs-dir``, of the sweeps' runs on ``bus``'s semantics: runs from
    before the switches existed, in runs/bus, ran the corrected semantics."""
    return "bus" if bus.semantics == "corrected" else f"bus-{bus.semantics}"


def jobs(cfg: BusSweepConfig, sweep: str, seed: int, bus: BusConfig) -> list[TrainJob]:
    out = []
    for lam, batch in cfg.settings(sweep):
        for s in range(seed, seed + cfg.seeds):
            train = train_config("quick", "bus", cfg.learner, seed=s, epochs=cfg.epochs,
                                 **{cfg.unit: batch}, lam=lam, fvp_subsample=cfg.fvp_subsample,
                                 sampler=cfg.sampler if cfg.pool else None)
            size = "batch" if cfg.unit == "batch_episodes" else "dec"
            pool = "pool_" if cfg.pool else ""
            out.append(TrainJob(f"{pool}lam{lam:g}_{size}{batch}_seed{s}", train, bus))
    return out


def curves(cfg: BusSweepConfig, job_list: list[TrainJob], root: Path) -> pd.DataFrame:
    """Per-run-per-epoch returns of the finished jobs."""
    frames = []
    for job in job_list:
        prog = pd.read_csv(run_dir(root, job) / "progress.csv").iloc[:cfg.epochs]
        pool = {"distinct_episodes": prog.distinct_episodes} if cfg.pool else {}
        frames.append(pd.DataFrame({
            "lambda": job.train.lam, "batch": getattr(job.train, cfg.unit), "seed": job.train.seed,
            "epoch": prog.epoch, "average_return": prog.average_return,
            "average_discounted_return": prog.average_discounted_return, **pool}))
    return pd.concat(frames, ignore_index=True)


def final_returns(cfg: BusSweepConfig, table: pd.DataFrame) -> pd.DataFrame:
    """One row per run: lambda, batch, seed, final_return (mean of its last final_epochs)."""
    last = table[table.epoch >= cfg.epochs - cfg.final_epochs]
    return (last.groupby(["lambda", "batch", "seed"], sort=False).average_return.mean()
            .rename("final_return").reset_index())


def convergence(table: pd.DataFrame, early_epochs: int, final_epochs: int,
                thresholds: float) -> pd.DataFrame:
    """One row per run of a sweep's per-epoch ``table``: lambda, batch, seed, early_return (mean
    of its first ``early_epochs`` epochs), epochs_to_thresholds (1 + the first epoch whose
    average return reaches ``thresholds``; NaN if none does) and final_return (mean of its last
    ``final_epochs``)."""
    rows = []
    for (lam, batch, seed), run in table.groupby(["lambda", "batch", "seed"], sort=False):
        ret = run.sort_values("epoch").average_return.to_numpy()
        reached = np.flatnonzero(ret >= thresholds)
        rows.append({"lambda": lam, "batch": batch, "seed": seed,
                     "early_return": float(ret[:early_epochs].mean()),
                     "epochs_to_thresholds": float(reached[0] + 1) if reached.size else np.nan,
                     "final_return": float(ret[-final_epochs:].mean())})
    return pd.DataFrame(rows)


def baseline_returns(results: Path, bus: BusConfig) -> dict[str, float]:
    """Average return of No Holding and of the Optimized Thresholds in ``results``."""
    thresholds = ThresholdPolicy(read_thresholds(results, "--results-dir"),
                                 headway_in_minutes=not bus.b2_headway)
    env = make_env(bus)
    return {name: float(env.rollout(policy, 1).episode_return[0])
            for name, policy in (("nohold", no_holding), ("thresholds", thresholds))}


def summary(cfg: BusSweepConfig, finals: pd.DataFrame, baselines: dict[str, float], seed: int,
            runs: dict[tuple[float, int, int], Path] | None = None) -> pd.DataFrame:
    """IQM and bootstrap CI of the final return per setting, the baselines, and (given ``runs``,
    (lambda, batch, seed) -> run folder) one row per run."""
    rng = np.random.default_rng(seed)
    rows = []
    for (lam, batch), grp in finals.groupby(["lambda", "batch"], sort=False):
        point, lo, hi = bootstrap_ci(grp.final_return.to_numpy(), iqm, n_boot=cfg.n_boot, rng=rng)
        rows.append(dict(policy="mlp", **{"lambda": lam}, batch=batch, runs=len(grp),
                         final_iqm=point, ci_low=lo, ci_high=hi, run=""))
    for name, ret in baselines.items():
        rows.append(dict(policy=name, **{"lambda": np.nan}, batch=np.nan, runs=1, final_iqm=ret,
                         ci_low=ret, ci_high=ret, run=""))
    for lam, batch, s, ret in zip(finals["lambda"], finals.batch, finals.seed, finals.final_return):
        if runs is not None:
            rows.append(dict(policy="mlp-run", **{"lambda": lam}, batch=batch, runs=1,
                             final_iqm=ret, ci_low=ret, ci_high=ret,
                             run=str(runs[(lam, batch, s)])))
    return pd.DataFrame(rows).astype({"batch": "Int64"})  # the baselines have no batch


def plot(cfg: BusSweepConfig, sweep: str, table: pd.DataFrame, baselines: dict[str, float],
         stem: Path, sources: list[Path]) -> None:
    """Mean training curve per setting with its 95% t-interval, the baselines as lines;
    ``sources``: the curves' CSV and the summary's (which holds the baselines)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy import stats as sps

    fig, axes = plt.subplots(2 if cfg.pool else 1, 1, sharex=True, squeeze=False,
                             figsize=(6.4, 6.6 if cfg.pool else 4.2),
                             gridspec_kw=dict(height_ratios=[3, 1.3][:1 + cfg.pool]))
    ax = axes[0, 0]
    for lam, batch in cfg.settings(sweep):
        sel = table[(table["lambda"] == lam) & (table.batch == batch)]
        if cfg.pool:
            distinct = sel.groupby("epoch").distinct_episodes.mean()
            axes[1, 0].plot(distinct.index, distinct, lw=1.0)
        by_epoch = sel.groupby("epoch").average_return
        mean, n = by_epoch.mean(), by_epoch.count()
        half = by_epoch.sem().fillna(0.0) * sps.t.ppf(0.975, np.maximum(n - 1, 1))
        label = f"$\\lambda$ = {lam:g}" if sweep == "lambda" else f"batch {batch}"
        line, = ax.plot(mean.index, mean, lw=1.2, label=label)
        ax.fill_between(mean.index, mean - half, mean + half, color=line.get_color(), alpha=0.2)
    ax.axhline(baselines["thresholds"], color="k", ls="--", lw=1, label="Optimized Thresholds")
    ax.axhline(baselines["nohold"], color="k", ls=":", lw=1, label="No Holding")
    fixed = (f"batch {cfg.lambda_batch} {cfg.unit.split('_')[1]}/epoch" if sweep == "lambda"
             else f"$\\lambda$ = {cfg.batch_lambda:g}")
    pool = ", released pool" if cfg.pool else ""
    ax.set_title(f"Bus holding, PS-TRPO + M-GAE, {learner_label(cfg.learner)}{pool} ({fixed}; "
                 f"{cfg.seeds} seeds, 95% CI)", fontsize=9)
    ax.set_ylabel("Average return per episode")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    if cfg.pool:
        axes[1, 0].set_ylabel("Distinct episodes\nper batch (mean)", fontsize=8)
        axes[1, 0].set_yscale("log")
        axes[1, 0].grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("Epoch")
    save_figure(fig, stem, sources)


FLAGS = ("seeds", "epochs", "final_epochs", "early_epochs", "sampler")
"""The BusSweepConfig fields the sweeps take as flags, besides ``--learner``."""
VARIANTS = ("sampler", *BUS_VARIANTS)
"""The options that choose the study (``*_pool``; the semantics, :func:`semantics_folder`), not
its settings (:func:`repro.studies.kit.options.scale_departures`)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_study_arguments(p, BusSweepConfig, FLAGS)
    add_learner_option(p, "bus_<sweep>_suite*")
    add_switch_arguments(p)
    add_replot(p)


def replot(sweep: str, cfg: BusSweepConfig, folders: Folders) -> int:
    """``--replot``: ``sweep``'s figure from its CSVs in the results folder, the baselines from
    its summary, titled with the sweep's settings as its sidecar records them."""
    names = [f"{cfg.stem(sweep)}.csv", f"{cfg.stem(sweep)}_summary.csv"]
    table, summ = read_for_replot(folders, *names)
    prov = read_provenance(folders.results / names[0])
    cfg = from_recorded(BusSweepConfig, prov["config"])
    baselines = {name: float(summ[summ.policy == name].final_iqm.iloc[0])
                 for name in ("nohold", "thresholds")}
    figures, sources = replot_figures(folders, *names)
    plot(cfg, sweep, table, baselines, figures / cfg.stem(sweep), sources)
    print(f"wrote {figures / cfg.stem(sweep)}.png/.pdf")
    return 0


def configure(args: argparse.Namespace) -> Command[tuple[BusSweepConfig, BusConfig]]:
    """A sweep's settings and the corridor's, of :func:`add_arguments`'s options."""
    cfg = sweep_config(args.scale, args.learner, **given_fields(args, BusSweepConfig, FLAGS))
    return Command.of(args, (cfg, config_from_args(args)))


def run_named(sweep: str, cmd: Command[tuple[BusSweepConfig, BusConfig]],
              folders: Folders) -> int:
    """The command of the sweep ``sweep`` ("lambda" or "batch")."""
    (cfg, bus), seed = cmd.study, cmd.seed
    folders = semantics_folders(folders, bus)
    if cmd.replot:
        return replot(sweep, cfg, folders)
    results, figures = folders.open()
    root = folders.run_root(runs_folder(bus))
    t0 = time.perf_counter()
    baselines = baseline_returns(results, bus)  # needs bus-thresholds: fails before training
    job_list = jobs(cfg, sweep, seed, bus)
    run_sweep(job_list, root, cmd.workers)
    table = curves(cfg, job_list, root)
    finals = final_returns(cfg, table)
    # the lambda sweep names its run folders: the figure drivers take the best policy from there
    runs = {(j.train.lam, getattr(j.train, cfg.unit), j.train.seed): run_dir(root, j)
            for j in job_list}
    summ = summary(cfg, finals, baselines, seed, runs if sweep == "lambda" else None)
    read = convergence(table, cfg.early_epochs, cfg.final_epochs, baselines["thresholds"])
    prov = provenance(cfg, command=f"fig-bus-{sweep}", scale=folders.scale, seed=seed,
                      wall_seconds=time.perf_counter() - t0, extra={"runs_dir": str(root)})
    sources = [write_result(results / f"{cfg.stem(sweep)}.csv", table, prov),
               write_result(results / f"{cfg.stem(sweep)}_summary.csv", summ, prov),
               write_result(results / f"{cfg.stem(sweep)}_convergence.csv", read, prov)]
    plot(cfg, sweep, table, baselines, figures / cfg.stem(sweep), sources)
    print(summ[summ.policy != "mlp-run"].to_string(index=False))
    return 0
