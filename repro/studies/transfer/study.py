"""The transfer study's pieces that its commands share (``transfer``, ``transfer-dt``,
``transfer-order``, ``transfer-ablation``, ``transfer-inputs``, ``transfer-heuristics``,
``advantage-estimators``): its config, its training jobs and their run folders, the test of every
trained policy on ED, the summary and the effect of a pair of simulators."""

from __future__ import annotations

import argparse
import io
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pandas as pd

from repro.core.config import add_config_arguments, for_scale, from_recorded, given_fields
from repro.core.rollout import children
from repro.envs.wildfire import (QUIRKS, RELEASED_VERSION, SIM_VERSIONS, WildfireConfig, make_env,
                                 version_suffix)
from repro.learn.config import (BATCH_UNITS, LEARNERS, SAMPLERS, SETTING_FIELDS,
                                add_study_learner_arguments, batch_unit, learner_suffix,
                                setting_tag)
from repro.paper import TRANSFER_ADR
from repro.runs.stats import bootstrap_ci, iqm, sem
from repro.studies.kit.options import ONE_PROCESS, Folders, Workers, add_common
from repro.studies.kit.sweep import (TrainJob, add_sweep_arguments, map_tasks, policy_stream,
                                     run_sweep)
from repro.studies.kit.training import StudyTraining
from repro.studies.wildfire.study import adr, evaluate


# Independent child streams of the root seed.
_TEST_ENV_STREAM, _TEST_POLICY_STREAM, _BOOT_STREAM = 0, 1, 2


@dataclass(frozen=True)
class TransferConfig(StudyTraining):
    """Sizes of the transfer study; the simulators and their semantics never change with scale.
    How each policy trains: :class:`~repro.studies.kit.training.StudyTraining`."""

    seeds: int = 3
    """Policies trained from scratch per training simulator (paper: 5)."""
    epochs: int = 60
    """Training epochs per policy (paper: 300)."""
    settings: tuple[tuple[str, Any], ...] = ()
    """Learner settings changed from the learner's, as (TrainConfig field, value) pairs (an
    ablation, ``learner-ablation``); each adds a tag to the file stem."""
    sampler: str = "independent"
    """The runs' batch sampler (``repro.learn.config.SAMPLERS``): "independent", every episode its
    own seeded stream; "released-pool", the released runner's unseeded workers sharing one stream,
    as the paper's transfer runs were trained (:mod:`repro.learn.pool`; needs a batch counted in
    decisions). The pool writes ``*_pool``."""
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

    ALIASES: ClassVar[dict[str, str]] = {"simulator": "only", "no_quirk": "quirks_off"}
    SCALES: ClassVar[dict] = {
        "smoke": dict(seeds=1, epochs=2, batch_episodes=8, batch_decisions=300, test_episodes=20,
                      n_boot=200),
        "quick": {},
        "paper": dict(seeds=5, epochs=300, batch_episodes=600, batch_decisions=12000,
                      test_episodes=10000),
    }

    def validate(self) -> None:
        super().validate()
        self.check(self.test_episodes >= 1, "test_episodes", "an integer >= 1")
        self.check(self.sim_version in SIM_VERSIONS, "sim_version",
                   "one of " + ", ".join(SIM_VERSIONS))
        self.check(all(k in SETTING_FIELDS for k, _ in self.settings), "settings",
                   "fields among " + ", ".join(SETTING_FIELDS))
        self.check(self.sampler in SAMPLERS, "sampler", "one of " + ", ".join(SAMPLERS))
        self.check(not self.pool or "sampler" not in dict(self.settings), "sampler",
                   "given once, not also among the settings")
        self.check(not self.pool or self.unit == "batch_decisions", "sampler",
                   "independent for a learner that counts its batch in episodes")
        self.check(all(-8 <= x <= 2 for x in self.log10_dts), "log10_dts",
                   "exponents in [-8, 2] (dT from 10 ns to 100 s)")
        self.check(-8 <= self.variant_log10_dt <= 2, "variant_log10_dt",
                   "in [-8, 2] (dT from 10 ns to 100 s)")
        self.check(self.variant_t_health > 0, "variant_t_health", "> 0")
        self.check(self.n_boot >= 1, "n_boot", "an integer >= 1")
        short = [q.split("_")[1] for q in QUIRKS]
        self.check(set(self.quirks_off) <= set(short), "quirks_off", "one of " + ", ".join(short))
        labels = list(self.simulators(every=True))
        self.check(set(self.only) <= set(labels), "only", "one of " + ", ".join(labels))

    @property
    def pool(self) -> bool:
        """Whether the runs sample with the released pool."""
        return self.sampler == "released-pool"

    @property
    def unit(self) -> str:
        """The TrainConfig field the runs' batch fills: the settings' batch size, else the
        learner's unit."""
        given = dict(self.settings)
        return next((u for u in BATCH_UNITS if u in given), batch_unit(LEARNERS[self.learner]))

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
        _no_fire_out_first for the reversed order, _suite for the suite's learner, _20170422
        for the simulator of 2017-04-22, and _pool for the released pool."""
        return "_".join(("transfer", *study_suffixes(self)))


def study_suffixes(cfg: TransferConfig) -> tuple[str, ...]:
    """The parts of a transfer study's file stem that name its semantics, learner, version and
    sampler."""
    parts = ("corrected",) if cfg.corrected else tuple(f"no_{q}" for q in sorted(cfg.quirks_off))
    order = () if cfg.fire_out_first else ("no_fire_out_first",)
    settings = tuple(setting_tag(k, v) for k, v in cfg.settings)
    return (*parts, *order, *learner_suffix(cfg.learner), *settings,
            *version_suffix(cfg.sim_version), *(("pool",) if cfg.pool else ()))


def batch_label(cfg: TransferConfig) -> str:
    """The batch as a figure title says it: "12000 decisions" or "600 episodes"."""
    unit = cfg.unit
    return f"{dict(cfg.settings).get(unit, getattr(cfg, unit))} {unit.split('_')[1]}"


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
    settings = (*cfg.settings, *((("sampler", cfg.sampler),) if cfg.pool else ()))
    jobs = []
    for label, env in cfg.simulators().items():
        for s in range(seed, seed + cfg.seeds):
            train = cfg.train_config(scale, s, settings)
            jobs.append((label, TrainJob(job_name(env, s), train, env)))
    return jobs


def test_env_seed(seed: int) -> int:
    """The environment seed of the ED test episodes (the same for every policy tested)."""
    return int(np.random.SeedSequence(seed, spawn_key=(_TEST_ENV_STREAM,)).generate_state(1)[0])


def evaluate_policies(cfg: TransferConfig, labelled: list[tuple[str, TrainJob]],
                      folders: list[Path], seed: int,
                      workers: Workers = ONE_PROCESS) -> pd.DataFrame:
    """One row per trained policy: its ADR on the ED test simulator under both protocols, and the
    training and test episodes that ended at the decision limit.

    - ``adr_ed`` (SEM ``adr_ed_sem``): the final policy on ``test_episodes`` episodes;
    - ``adr_ed_kept``: the released runner's evaluation: the policies after each of the run's last
      ``KEPT_POLICIES`` epochs (the snapshots of iterations 260-299 of 300), each on one stochastic
      ED episode of its own, averaged. The episodes are the run's own, not common to all runs as
      the final policy's are: the released runner drew them afresh, so its error bars include
      the episodes' spread, and 40 common episodes would shift every run alike (by about 0.1 ADR
      in a trial).

    The policies are tested in parallel like a sweep (``map_tasks``); each has its own stream,
    keyed by its run (:func:`~repro.studies.kit.sweep.policy_stream`), so the numbers do not depend
    on where or in which order they run, nor on which other policies a study tests."""
    from repro.learn.config import learner_name
    from repro.runs.run_folder import CHECKPOINT, KEPT_POLICIES, kept_policies

    env_seed = test_env_seed(seed)
    tasks = []
    for (_, job), folder in zip(labelled, folders):
        kept = kept_policies(folder, min(KEPT_POLICIES, job.train.epochs), job.train.epochs)
        tasks.append((cfg.test_simulator(), (folder / CHECKPOINT).read_bytes(),
                      [p.read_bytes() for p in kept], cfg.test_episodes, env_seed,
                      policy_stream(seed, _TEST_POLICY_STREAM, job.name)))
    scores = map_tasks(score_policy, tasks, workers)
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
    from repro.runs.run_folder import load_checkpoint
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
        paper_mean, paper_sem = TRANSFER_ADR.get(label, (np.nan, np.nan))
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


SIZES = ("seeds", "epochs", "test_episodes")
"""The TransferConfig fields that every study of the transfer family takes as flags, besides the
learner and its batch sizes (:func:`repro.learn.config.add_study_learner_arguments`)."""
SEMANTICS = ("corrected", "quirks_off", "fire_out_first", "sim_version", "sampler", "only")
"""The TransferConfig fields that choose the simulators a transfer study trains and tests on, and
how it samples: flags of the drivers that let a user choose them."""


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
    return for_scale(TransferConfig, args.scale, **{**given_fields(args, TransferConfig),
                                                    **fields})


def runs_folder(folders: Folders, cfg: TransferConfig) -> Path:
    """The folder of the study's run folders in the runs folder: one per semantics and scale
    (UsageError naming ``--runs-dir`` if it cannot be written)."""
    return folders.run_root(cfg.name.replace("_", "-"), folders.scale)


def train_and_test(cfg: TransferConfig, folders: Folders, labelled: list[tuple[str, TrainJob]],
                   seed: int, workers: Workers) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Train (or resume) the ``labelled`` jobs in the study's run folders on ``workers``, then
    test every policy on ED (``seed``: the root seed); returns the per-policy table and the
    sweep's timing for the provenance sidecar."""
    runs = runs_folder(folders, cfg)
    t0 = time.perf_counter()
    done = run_sweep([job for _, job in labelled], runs, workers)
    t_train = time.perf_counter() - t0
    per_policy = evaluate_policies(cfg, labelled, done, seed, workers)
    seconds = [pd.read_csv(f / "progress.csv").seconds for f in done]
    # the median skips each worker's first epoch, which includes numba's start-up
    return per_policy, dict(
        runs_dir=str(runs), sweep_seconds=round(t_train, 3),
        median_seconds_per_epoch=round(float(np.median(np.concatenate(seconds))), 4))


def recorded_config(prov: dict[str, Any]) -> TransferConfig:
    """The transfer study's config that a result's sidecar records."""
    return from_recorded(TransferConfig, prov["config"])


_EFFECT_STREAM = 4
"""Child of the root seed for the effects' bootstrap in the order study (the transfer study and the
heuristics use 0-3)."""


def effects(per_policy: pd.DataFrame, pair: tuple[str, str], n_boot: int, seed: int,
            by: tuple[str, ...] = ("semantics", "order"), score: str = "adr_ed",
            stream: int = _EFFECT_STREAM) -> pd.DataFrame:
    """Per group of the ``by`` columns: mean ``score`` of the T_health variant (``pair[0]``) minus
    that of FS (``pair[1]``), with a percentile bootstrap CI that resamples each simulator's
    policies within itself (from child ``stream`` of the root seed)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(stream,)))
    rows = []
    for key, g in per_policy.groupby(list(by), sort=False):
        low, ref = (g[g.simulator == label][score].to_numpy() for label in pair)
        diff, lo, hi = bootstrap_ci(np.column_stack([low, ref]),
                                    lambda x: x[:, 0].mean() - x[:, 1].mean(), n_boot=n_boot,
                                    rng=rng)
        rows.append(dict(zip(by, key), n_policies=len(low), adr_variant=float(low.mean()),
                         adr_fs=float(ref.mean()), difference=diff, ci_low=lo, ci_high=hi,
                         degrades=bool(hi < 0)))
    return pd.DataFrame(rows)
