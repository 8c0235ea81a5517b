"""Policy transfer from fixed-step to event-driven simulation (paper Fig. "transferperformance",
claims C8 and C9; docs/semantics.md section 6.2).

Policies are trained from scratch (PS-TRPO + M-GAE, ``repro.learn``) on each training simulator: ED,
FS-dT for the paper's five dT values, and FS-1 with T_health = 2.9999. Every trained policy is then
tested on the ED simulator with T_health = 3.0: its ADR (docs/semantics.md section 6.1) over
``test_episodes`` episodes. All policies see the same test episodes (one environment seed), so
differences between them are not test-episode noise; each policy samples its actions from its own
generator.

The paper averages the test ADR of the last epochs' policies; we test each run's final policy (the
one its checkpoint holds) on many episodes, which estimates the same quantity once training has
reached its asymptote (the per-run ``train_adr_last`` column shows the training-curve plateau).

Per simulator the summary gives the mean over the trained policies with its standard error (the
paper's error bars), the IQM, and a bootstrap CI of the mean (``repro.core.stats``).

``--corrected`` trains and tests with quirks Q1-Q6 switched off (the paper's prose) and writes
``transfer_corrected*.csv`` and ``figures/transfer_corrected.*`` instead; a quirk's flag, as
``train`` spells it (``--no-quirk-q3-unclamped-health``; the old ``--no-quirk q3`` too), switches
one quirk off (``transfer_no_q3*``), ``--no-fire-out-first`` reverses the same-instant order of a
macro-action's end and a fire's extinguishing (``*_no_fire_out_first``; claim X4).

Training runs are checkpointed under ``--runs-dir``/transfer[-corrected]/<scale>/; re-running
skips finished runs and resumes interrupted ones (``repro.experiments.sweep``).
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pandas as pd

from repro.core.config import (Validated, add_config_arguments, for_scale, from_recorded,
                               given_fields)
from repro.core.errors import require
from repro.core.io import (check_writable_dir, provenance, read_provenance, save_figure,
                           write_result)
from repro.core.rollout import children
from repro.core.stats import bootstrap_ci, iqm, sem
from repro.envs.wildfire import (QUIRKS, RELEASED_VERSION, SIM_VERSIONS, WildfireConfig, make_env,
                                 version_suffix)
from repro.learn.config import (LEARNERS, SETTING_FIELDS, add_study_learner_arguments,
                                check_policy_study, learner_label, learner_suffix, setting_tag)
from repro.experiments.options import add_common, add_replot, read_for_replot, replot_figures
from repro.experiments.sweep import (TrainJob, add_sweep_arguments, check_study_arguments,
                                     map_tasks, run_sweep)
from repro.experiments.wildfire_eval import adr, evaluate

PAPER = {
    "ED": (2.780, 0.014), "FS-0.1": (2.771, 0.018), "FS-0.316": (2.745, 0.015),
    "FS-1": (2.789, 0.009), "FS-3.16": (2.212, 0.082), "FS-10": (1.841, 0.179),
    "FS-1 (T_health=2.9999)": (1.937, 0.041),
}
"""Paper, Fig. "transferperformance": ADR on ED, mean and standard error over 5 policies."""

# Independent child streams of the root seed.
_TEST_ENV_STREAM, _TEST_POLICY_STREAM, _BOOT_STREAM = 0, 1, 2


@dataclass(frozen=True)
class TransferConfig(Validated):
    """Sizes of the transfer study; the simulators and their semantics never change with scale."""

    seeds: int = 3
    """Policies trained from scratch per training simulator (paper: 5)."""
    epochs: int = 60
    """Training epochs per policy (paper: 300)."""
    learner: str = "authors"
    """The named learner that trains every policy (``repro.learn.config.LEARNERS``)."""
    batch_decisions: int = 3000
    """Training decisions per epoch when the learner counts its batch in decisions (the released
    runner: 12,000)."""
    batch_episodes: int = 150
    """Training episodes per epoch when the learner counts its batch in episodes (the paper's
    table: 600 to 1,200)."""
    settings: tuple[tuple[str, Any], ...] = ()
    """Learner settings changed from the learner's, as (TrainConfig field, value) pairs (an
    ablation, ``learner-ablation``); each adds a tag to the file stem."""
    sim_version: str = RELEASED_VERSION
    """The released simulator's version every simulator of the study follows
    (``repro.envs.wildfire.SIM_VERSIONS``): the released HEAD, or "2017-04-22", the one the
    paper's transfer runs were trained on (crowding penalty 1)."""
    test_episodes: int = 2000
    """ED test episodes per trained policy."""
    log10_dts: tuple[float, ...] = (-1.0, -0.5, 0.0, 0.5, 1.0)
    """The FS training simulators: dT = 10^x seconds (the paper's five)."""
    variant_t_health: float = 2.9999
    """T_health of the extra FS training simulator of C9 (tested with 3.0 like every policy)."""
    variant_log10_dt: float = 0.0
    """dT = 10^x of that extra simulator (paper: 1 s)."""
    corrected: bool = False
    """Train and test with quirks Q1-Q6 switched off (the paper's prose semantics; the released
    same-instant order stays)."""
    quirks_off: tuple[str, ...] = ()
    """Quirks switched off in every simulator, by short name ("q3"): an ablation between the
    released semantics (none) and the corrected ones (all, ``corrected``)."""
    fire_out_first: bool = True
    """The released same-instant order of a UAV's macro-action end and a fire's extinguishing in
    every simulator; False reverses it (``WildfireConfig.fire_out_first``; claim X4)."""
    only: tuple[str, ...] = ()
    """Training simulators to run, by label ("FS-1"); empty: all of them."""
    n_boot: int = 2000
    """Bootstrap replicates of each simulator's CI."""

    SCALES: ClassVar[dict] = {
        "smoke": dict(seeds=1, epochs=2, batch_episodes=8, batch_decisions=300, test_episodes=20,
                      n_boot=200),
        "quick": {},
        "paper": dict(seeds=5, epochs=300, batch_episodes=600, batch_decisions=12000,
                      test_episodes=10000),
    }

    def validate(self) -> None:
        check_policy_study(self)
        self.check(self.sim_version in SIM_VERSIONS, "sim_version",
                   "one of " + ", ".join(SIM_VERSIONS))
        self.check(all(k in SETTING_FIELDS for k, _ in self.settings), "settings",
                   "fields among " + ", ".join(SETTING_FIELDS))
        self.check(all(-8 <= x <= 2 for x in self.log10_dts), "log10_dts",
                   "exponents in [-8, 2] (dT from 10 ns to 100 s)")
        self.check(-8 <= self.variant_log10_dt <= 2, "variant_log10_dt",
                   "in [-8, 2] (dT from 10 ns to 100 s)")
        self.check(self.variant_t_health > 0, "variant_t_health", "> 0")
        self.check(self.n_boot >= 1, "n_boot", "an integer >= 1")
        short = [q.split("_")[1] for q in QUIRKS]
        require(set(self.quirks_off) <= set(short), "--no-quirk", "one of " + ", ".join(short),
                list(self.quirks_off))
        labels = list(self.simulators(every=True))
        require(set(self.only) <= set(labels), "--simulator", "one of " + ", ".join(labels),
                list(self.only))

    def quirks(self) -> dict[str, bool]:
        """The quirk switches of every simulator of the study (train and test alike)."""
        return {q: not self.corrected and q.split("_")[1] not in self.quirks_off for q in QUIRKS}

    def simulator(self, **fields) -> WildfireConfig:
        """A simulator of the study: its quirks and same-instant order, and ``fields``."""
        return WildfireConfig(**self.quirks(), fire_out_first=self.fire_out_first,
                              **SIM_VERSIONS[self.sim_version], **fields)

    def simulators(self, every: bool = False) -> dict[str, WildfireConfig]:
        """Training simulators by label (the paper's figure order): those of ``only``, or
        ``every`` one."""
        sims = {"ED": self.simulator()}
        for x in self.log10_dts:
            sims[fs_label(10.0 ** x)] = self.simulator(dt=10.0 ** x)
        sims[self.variant_pair()[0]] = self.simulator(dt=10.0 ** self.variant_log10_dt,
                                                      t_health=self.variant_t_health)
        return sims if every or not self.only else {k: v for k, v in sims.items() if k in self.only}

    def variant_pair(self) -> tuple[str, str]:
        """C9's two simulators: the T_health variant and the FS simulator of its dT."""
        fs = fs_label(10.0 ** self.variant_log10_dt)
        return f"{fs} (T_health={self.variant_t_health:g})", fs

    def test_simulator(self) -> WildfireConfig:
        """ED with T_health = 3.0, the simulator every policy is tested on."""
        return self.simulator()

    @property
    def name(self) -> str:
        """File stem of the results: transfer, transfer_corrected, or transfer_no_q3 (say), then
        _no_fire_out_first for the reversed order, _suite for the suite's learner, and _20170422
        for the simulator of 2017-04-22."""
        return "_".join(("transfer", *study_suffixes(self)))


def study_suffixes(cfg: TransferConfig) -> tuple[str, ...]:
    """The parts of a transfer study's file stem that name its semantics, learner and version."""
    parts = ("corrected",) if cfg.corrected else tuple(f"no_{q}" for q in sorted(cfg.quirks_off))
    order = () if cfg.fire_out_first else ("no_fire_out_first",)
    settings = tuple(setting_tag(k, v) for k, v in cfg.settings)
    return (*parts, *order, *learner_suffix(cfg.learner), *settings,
            *version_suffix(cfg.sim_version))


def batch_label(cfg: TransferConfig) -> str:
    """The batch as a figure title says it: "12000 decisions" or "600 episodes"."""
    given = dict(cfg.settings)
    unit = next((u for u in ("batch_decisions", "batch_episodes") if u in given),
                LEARNERS[cfg.learner]["batch_unit"])
    return f"{given.get(unit, getattr(cfg, unit))} {unit.split('_')[1]}"


def fs_label(dt: float) -> str:
    """The paper's label of FS-dT (three significant digits: FS-0.316, FS-3.16)."""
    return f"FS-{dt:.3g}"


def job_name(env: WildfireConfig, seed: int) -> str:
    """A folder-safe run name, e.g. ``fs0.316-th3-seed2``."""
    sim = "ed" if env.dt is None else f"fs{env.dt:.3g}"
    return f"{sim}-th{env.t_health:g}-seed{seed}"


def make_jobs(cfg: TransferConfig, scale: str, seed: int) -> list[tuple[str, TrainJob]]:
    """(simulator label, job) for every simulator and training seed seed .. seed + seeds - 1.

    Replicate r uses the same training seed on every simulator (common initial policies)."""
    from repro.learn.config import study_train_config

    jobs = []
    for label, env in cfg.simulators().items():
        for s in range(seed, seed + cfg.seeds):
            train = study_train_config(scale, "wildfire", cfg.learner, cfg.batch_decisions,
                                       cfg.batch_episodes, cfg.settings, seed=s,
                                       epochs=cfg.epochs)
            jobs.append((label, TrainJob(job_name(env, s), train, env)))
    return jobs


def test_env_seed(seed: int) -> int:
    """The environment seed of the ED test episodes (the same for every policy tested)."""
    return int(np.random.SeedSequence(seed, spawn_key=(_TEST_ENV_STREAM,)).generate_state(1)[0])


def evaluate_policies(cfg: TransferConfig, labelled: list[tuple[str, TrainJob]],
                      folders: list[Path], seed: int, *, n_jobs: int | None = 1,
                      scheduler: str | None = None) -> pd.DataFrame:
    """One row per trained policy: its ADR on the ED test simulator under both protocols, and the
    training and test episodes that ended at the decision limit.

    - ``adr_ed`` (SEM ``adr_ed_sem``): the final policy on ``test_episodes`` episodes;
    - ``adr_ed_kept``: the released runner's evaluation: the policies after each of the run's last
      ``KEPT_POLICIES`` epochs (the snapshots of iterations 260-299 of 300), each on one stochastic
      ED episode of its own, averaged. The episodes are the run's own, not common to all runs as
      the final policy's are: the released runner drew them afresh, so its error bars include
      the episodes' spread, and 40 common episodes would shift every run alike (by about 0.1 ADR
      in a trial).

    The policies are tested in parallel like a sweep (``map_tasks``); each has its own stream, so
    the numbers do not depend on where or in which order they run."""
    from repro.learn.config import learner_name
    from repro.learn.run_folder import CHECKPOINT, KEPT_POLICIES, kept_policies

    env_seed = test_env_seed(seed)
    tasks = []
    for i, ((_, job), folder) in enumerate(zip(labelled, folders)):
        kept = kept_policies(folder, min(KEPT_POLICIES, job.train.epochs), job.train.epochs)
        tasks.append((cfg.test_simulator(), (folder / CHECKPOINT).read_bytes(),
                      [p.read_bytes() for p in kept], cfg.test_episodes, env_seed,
                      np.random.SeedSequence(seed, spawn_key=(_TEST_POLICY_STREAM, i))))
    scores = map_tasks(score_policy, tasks, n_jobs=n_jobs, scheduler=scheduler)
    rows = []
    for ((label, job), folder), (mean, err, test_cut, kept) in zip(zip(labelled, folders), scores):
        curve = pd.read_csv(folder / "progress.csv")
        last = curve.average_discounted_return.iloc[-max(1, len(curve) // 10):]
        rows.append(dict(simulator=label, dt=job.env_config.dt or 0.0,  # 0 stands for ED
                         t_health=job.env_config.t_health, r_pen=job.env_config.r_pen,
                         train_seed=job.train.seed, learner=learner_name(job.train),
                         epochs=len(curve), batch_episodes=float(curve.batch_episodes.mean()),
                         batch_decisions=float(curve.decisions.mean()),
                         test_episodes=cfg.test_episodes, adr_ed=mean, adr_ed_sem=err,
                         adr_ed_kept=kept, train_adr_last=float(last.mean()),
                         max_decisions=job.env_config.max_decisions or 0,
                         train_truncated=int(curve.truncated_episodes.sum()),
                         test_truncated=test_cut, run=job.name))
    return pd.DataFrame(rows)


def score_policy(env_cfg: WildfireConfig, checkpoint: bytes, kept: list[bytes], episodes: int,
                 env_seed: int, policy_stream: np.random.SeedSequence
                 ) -> tuple[float, float, int, float]:
    """ADR, its standard error and the episodes cut at the decision limit, of the policy of
    ``checkpoint`` (its bytes, so that a worker without the client's disk can test it) on
    ``episodes`` episodes of ``env_cfg``; then the mean ADR of the ``kept`` policies, each on
    one episode drawn from ``policy_stream`` (the released runner's evaluation)."""
    from repro.learn.run_folder import load_checkpoint
    from repro.learn.trained_policy import policy_from_state

    env = make_env(env_cfg)
    sizes = dict(obs_dim=env.obs_dim, n_actions=env.n_actions)
    final, *kept_streams = children(policy_stream, 1 + len(kept))
    policy = policy_from_state(load_checkpoint(io.BytesIO(checkpoint), "--runs-dir", **sizes),
                               np.random.default_rng(final))
    rollout = evaluate(env, policy, episodes, env_seed, keep_obs=False)
    kept_adr = []
    for data, stream in zip(kept, kept_streams):
        actions, episode = children(stream, 2)
        kept_policy = policy_from_state(load_checkpoint(io.BytesIO(data), "--runs-dir", **sizes),
                                        np.random.default_rng(actions))
        kept_adr.append(adr(env.rollout(kept_policy, 1, episode), env.gamma)[0])
    return (*adr(rollout, env.gamma), rollout.n_truncated,
            float(np.mean(kept_adr)) if kept_adr else float("nan"))


def summarise(per_policy: pd.DataFrame, n_boot: int, seed: int) -> pd.DataFrame:
    """Per training simulator: mean, SEM over policies, IQM and a bootstrap CI of the mean."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_BOOT_STREAM,)))
    rows = []
    for label, grp in per_policy.groupby("simulator", sort=False):
        x, kept = grp.adr_ed.to_numpy(), grp.adr_ed_kept.to_numpy()
        _, lo, hi = bootstrap_ci(x, np.mean, n_boot=n_boot, rng=rng)
        paper_mean, paper_sem = PAPER.get(label, (np.nan, np.nan))
        rows.append(dict(simulator=label, dt=grp.dt.iloc[0], t_health=grp.t_health.iloc[0],
                         n_policies=len(x), mean=float(x.mean()), sem=sem(x), iqm=float(iqm(x)),
                         ci_low=lo, ci_high=hi, mean_kept=float(kept.mean()), sem_kept=sem(kept),
                         paper_mean=paper_mean, paper_sem=paper_sem,
                         z_paper=distance_in_se(x.mean(), sem(x), paper_mean, paper_sem),
                         z_paper_kept=distance_in_se(kept.mean(), sem(kept), paper_mean,
                                                     paper_sem)))
    return pd.DataFrame(rows)


def distance_in_se(mean: float, err: float, paper_mean: float, paper_err: float) -> float:
    """(mean - paper_mean) in combined standard errors, sqrt(err^2 + paper_err^2)."""
    return float((mean - paper_mean) / np.hypot(err, paper_err))


def plot(per_policy: pd.DataFrame, summary: pd.DataFrame, stem: Path, title: str,
         sources: list[Path]) -> None:
    """The paper's figure: x = training simulator, y = ADR on ED, error bars = SEM over policies;
    the T_health variant sits at its dT beside the T_health = 3.0 point; the paper's points beside
    ours. ``sources``: the per-policy and summary CSVs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tested = summary.t_health == WildfireConfig.t_health
    main, variant = summary[tested].reset_index(drop=True), summary[~tested]
    xpos = {label: i for i, label in enumerate(main.simulator)}
    for row in variant.itertuples():  # placed at the FS simulator of the same dT
        xpos[row.simulator] = xpos[fs_label(row.dt)]
    fig, ax = plt.subplots(figsize=(7, 4))
    for frame, marker, color, name in ((main, "o", "C0", "ours"),
                                       (variant, "s", "C3", "ours")):
        x = np.array([xpos[s] for s in frame.simulator], dtype=float)
        for label in frame.simulator:
            dots = per_policy[per_policy.simulator == label].adr_ed
            ax.plot(np.full(len(dots), xpos[label] - 0.12), dots, ".", color=color, alpha=0.4,
                    ms=4)
        th = frame.t_health.iloc[0] if len(frame) else 0
        ax.errorbar(x - 0.06, frame["mean"], yerr=frame["sem"], fmt=marker, color=color,
                    capsize=3, label=f"{name}, T_health = {th:g} (dots: each policy)")
        ax.errorbar(x + 0.06, frame.paper_mean, yerr=frame.paper_sem, fmt=marker, mfc="none",
                    color=color, alpha=0.7, capsize=3, label=f"paper, T_health = {th:g}")
    ax.set_xticks(range(len(main)), main.simulator)
    ax.set_xlabel("training simulator")
    ax.set_ylabel("ADR on ED (T_health = 3.0)\nmean over policies, error bars: standard error",
                  fontsize=9)
    ax.set_title(title, fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    save_figure(fig, stem, sources)


VARIANTS = ("corrected", "no_quirk", *QUIRKS, "sim_version", "no_fire_out_first")
"""Options that choose the study, each writing result files of its own (``transfer_corrected*``,
``*_no_q3*``, ``*_20170422``, ``*_no_fire_out_first``), not its settings
(:func:`repro.experiments.options.scale_departures`)."""
SIZES = ("seeds", "epochs", "test_episodes")
"""The TransferConfig fields that every study of the transfer family takes as flags, besides the
learner and its batch sizes (:func:`repro.learn.config.add_study_learner_arguments`)."""


def add_size_arguments(p: argparse.ArgumentParser, writes: str) -> None:
    """Every driver's options, the sweep's, and the transfer study's sizes (``beyond-order``,
    ``learner-ablation`` and ``c9-inputs`` train transfer studies too); ``writes``: the results
    another learner writes."""
    add_common(p)
    add_sweep_arguments(p)
    add_config_arguments(p, TransferConfig, SIZES)
    add_study_learner_arguments(p, writes)


def study_config(args: argparse.Namespace, **fields) -> TransferConfig:
    """The config of :func:`add_size_arguments`'s options at ``args.scale``, with ``fields``
    (None: the scale's)."""
    given = given_fields(args, TransferConfig, (*SIZES, "learner", "batch_decisions",
                                                "batch_episodes"))
    return for_scale(TransferConfig, args.scale, **{**given, **fields})


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_size_arguments(p, "transfer*_suite*")
    p.add_argument("--corrected", action="store_true",
                   help="quirks Q1-Q6 off (paper's prose); writes transfer_corrected*")
    # each quirk's flag as train spells it: --no-quirk-q3-unclamped-health switches Q3 off in
    # every simulator of the study (an ablation; writes transfer_no_q3*)
    add_config_arguments(p, WildfireConfig, QUIRKS)
    p.add_argument("--no-quirk", action="append", default=[], metavar="Q",
                   help="old spelling: --no-quirk q3 is --no-quirk-q3-unclamped-health "
                        "(repeatable)")
    p.add_argument("--simulator", action="append", default=[], metavar="LABEL",
                   help="train and test only this simulator (e.g. FS-1), repeatable")
    p.add_argument("--sim-version", choices=tuple(SIM_VERSIONS),
                   help="the released simulator's version (default 2017-05-16, the released "
                        "HEAD; 2017-04-22: the one the paper's runs were trained on); "
                        "2017-04-22 writes *_20170422")
    p.add_argument("--no-fire-out-first", action="store_true",
                   help="a UAV whose macro-action ends as a fire goes out observes first (the "
                        "released order reversed, X4); writes *_no_fire_out_first")
    add_replot(p)


def runs_folder(runs_dir: str | Path, cfg: TransferConfig, scale: str) -> Path:
    """The folder of the study's run folders: one per semantics and scale (UsageError naming
    ``--runs-dir`` if it cannot be written)."""
    return check_writable_dir(Path(runs_dir) / cfg.name.replace("_", "-") / scale, "--runs-dir")


def train_and_test(cfg: TransferConfig, args: argparse.Namespace,
                   labelled: list[tuple[str, TrainJob]]) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Train (or resume) the ``labelled`` jobs in the study's run folders, then test every
    policy on ED; returns the per-policy table and the sweep's timing for the provenance sidecar."""
    runs = runs_folder(args.runs_dir, cfg, args.scale)
    t0 = time.perf_counter()
    folders = run_sweep([job for _, job in labelled], runs, n_jobs=args.n_jobs,
                        scheduler=args.scheduler)
    t_train = time.perf_counter() - t0
    per_policy = evaluate_policies(cfg, labelled, folders, args.seed, n_jobs=args.n_jobs,
                                   scheduler=args.scheduler)
    seconds = [pd.read_csv(f / "progress.csv").seconds for f in folders]
    # the median skips each worker's first epoch, which includes numba's start-up
    return per_policy, dict(
        runs_dir=str(runs), sweep_seconds=round(t_train, 3),
        median_seconds_per_epoch=round(float(np.median(np.concatenate(seconds))), 4))


def config_from_args(args: argparse.Namespace) -> TransferConfig:
    """The study's config of :func:`add_arguments`'s options (UsageError if bad)."""
    off = [q.split("_")[1] for q, on in given_fields(args, WildfireConfig).items() if not on]
    return study_config(args, corrected=args.corrected or None,
                        quirks_off=tuple(sorted({*off, *(q.lower() for q in args.no_quirk)}))
                        or None,
                        only=tuple(args.simulator) or None,
                        fire_out_first=False if args.no_fire_out_first else None,
                        sim_version=args.sim_version)


def figure_title(cfg: TransferConfig, scale: str) -> str:
    """What the figure of a transfer study says of its runs."""
    semantics = ("quirks Q1-Q6 corrected" if cfg.corrected else
                 f"released semantics, {', '.join(cfg.quirks_off).upper()} off" if cfg.quirks_off
                 else "released semantics (Q1-Q6 on)")
    semantics += "" if cfg.fire_out_first else ", UAV before fire at one instant"
    return (f"Transfer to ED, {semantics}; {scale} scale: {cfg.seeds} policies x {cfg.epochs} "
            f"epochs x {batch_label(cfg)}, {learner_label(cfg.learner)}, simulator of "
            f"{cfg.sim_version}")


def replot(cfg: TransferConfig, args: argparse.Namespace) -> int:
    """``--replot``: the figure of the study ``cfg`` names, from its CSVs and the settings its
    sidecar records."""
    names = (f"{cfg.name}.csv", f"{cfg.name}_summary.csv")
    per_policy, summary = read_for_replot(args, *names)
    prov = read_provenance(Path(args.results_dir) / f"{cfg.name}.csv")
    recorded = recorded_config(prov)
    figures, sources = replot_figures(args, *names)
    stem = figures / cfg.name
    plot(per_policy, summary, stem, figure_title(recorded, prov["scale"]), sources)
    print(f"wrote {stem}.png/.pdf")
    return 0


def recorded_config(prov: dict[str, Any]) -> TransferConfig:
    """The transfer study's config that a result's sidecar records."""
    return from_recorded(TransferConfig, prov["config"])


def run(args: argparse.Namespace) -> int:
    cfg = config_from_args(args)
    if args.replot:
        return replot(cfg, args)
    results, figures = check_study_arguments(args)
    t0 = time.perf_counter()
    per_policy, extra = train_and_test(cfg, args, make_jobs(cfg, args.scale, args.seed))
    summary = summarise(per_policy, cfg.n_boot, args.seed)
    prov = provenance(dataclasses.asdict(cfg), command="fig-transfer", scale=args.scale,
                      seed=args.seed, wall_seconds=time.perf_counter() - t0, extra=extra)
    sources = [write_result(results / f"{cfg.name}.csv", per_policy, prov),
               write_result(results / f"{cfg.name}_summary.csv", summary, prov)]
    plot(per_policy, summary, figures / cfg.name, figure_title(cfg, args.scale), sources)
    print(summary[["simulator", "n_policies", "mean", "sem", "ci_low", "ci_high",
                   "paper_mean"]].to_string(index=False))
    return 0
