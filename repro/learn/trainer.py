"""PS-TRPO with M-GAE: the training loop (docs/semantics.md section 5.6).

One epoch = sample a batch of whole episodes with the current shared policy (``batch_episodes`` of
them, or, counted in decisions, as the released runner's parallel workers collected them:
:mod:`repro.learn.batch`, or with the released pool's shared random streams:
:mod:`repro.learn.pool`), compute M-GAE
advantages (or those of ``TrainConfig.advantage``) with the current baseline, take one TRPO step,
update the observation normaliser, then fit the baseline to the batch's discounted returns (in the
new normalisation, which it will be used with). Given a run folder, the trainer hands each epoch's
row and state to :mod:`repro.runs.run_folder`, which records them so that running the same
command again resumes exactly.

Threads and malloc: torch's thread count and malloc's thresholds are process-wide settings, which
the process's entry point makes once (:func:`repro.learn.process.configure_process`).

Determinism: torch is seeded from the run seed; the policy's sampling draws come from one numpy
Generator owned by the trainer (its state is checkpointed); epoch e's environment seed is derived
from (seed, e). Timing columns are the only run-to-run differences in the outputs. Across machines:
the learner's arithmetic is compiled loops whose sums run in a fixed order, with no library that
picks kernels by the CPU (:mod:`repro.runs.kernels`; the trainer warns where the pin of what
remains did not take), so on every x86-64 CPU with AVX2 and FMA, of any vendor, the outputs are
the same bytes. With the released pool the sampling draws come instead from the run's pool stream
at the workers' positions, which the checkpoint keeps too.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pandas as pd
import torch

from repro.core.errors import require
from repro.core.config import to_dict
from repro.core.rollout import BatchEnv, Rollout
from repro.learn import batch, gru
from repro.learn.baseline import make_baseline
from repro.learn.config import TrainConfig
from repro.learn.m_gae import advantage_paths
from repro.learn.network import TanhMLP
from repro.learn.policy import CategoricalPolicy, ObsNormalizer, Sampler
from repro.learn.pool import ReleasedPool, runs_on_pool
from repro.learn.run_identity import run_config, saved_run_aliases, saved_run_defaults
from repro.learn.sizes import check_training_size
from repro.learn.trpo import TRPOStats, normalize, trpo_step
from repro.runs import run_folder
from repro.runs.run_folder import PROGRESS_COLUMNS
from repro.runs.kernels import check as check_kernels
from repro.runs.progress import progress

# Independent child streams of the run seed.
_TORCH_STREAM, _SAMPLER_STREAM, _ENV_STREAM, _FVP_STREAM, _POOL_STREAM = 0, 1, 2, 3, 4


def _stream(seed: int, *key: int) -> np.random.SeedSequence:
    return np.random.SeedSequence(seed, spawn_key=key)


def epoch_seed(seed: int, epoch: int) -> np.random.SeedSequence:
    """The environment seed of ``epoch`` (0-based) of a run with root ``seed``."""
    return _stream(seed, _ENV_STREAM, epoch)


class Trainer:
    """Owns the policy, baseline, normaliser and sampling generator of one run, and its epoch.

    It changes no process-wide state: call :func:`repro.learn.process.configure_process` once
    before training, as the command line does."""

    def __init__(self, cfg: TrainConfig, env: BatchEnv, out: str | Path | None = None,
                 env_config: Any = None, param: str = "--out"):
        require(env.gamma > 0 and math.isfinite(env.gamma), "--gamma", "a number > 0", env.gamma)
        self.cfg, self.env = cfg, env
        self.out = None if out is None else Path(out)
        self.param = param
        """The option that named ``out`` (a sweep's is --runs-dir): refusals name it."""
        self.env_config = env_config
        self.run_config = run_config(cfg, env_config, env.name)
        require(cfg.sampler != "released-pool" or runs_on_pool(env), "--sampler",
                "independent for an environment that draws random numbers itself and cannot run "
                "given draws (the released pool is modelled where only the policy draws, the bus, "
                "or where episodes run on given draws, the wildfire)", cfg.sampler)
        check_training_size(cfg, env)  # before the networks are built
        check_kernels()
        torch.manual_seed(int(_stream(cfg.seed, _TORCH_STREAM).generate_state(1)[0]))
        self.policy = (gru.gru_policy(env.obs_dim, env.n_actions, to_dict(cfg))
                       if cfg.policy == "gru" else
                       CategoricalPolicy(env.obs_dim, env.n_actions, cfg.hidden, cfg.init))
        self.baseline = make_baseline(cfg.baseline, env.obs_dim, cfg.baseline_hidden,
                                      cfg.baseline_iters)
        self.normalizer = ObsNormalizer(env.obs_dim)
        self.rng = np.random.default_rng(_stream(cfg.seed, _SAMPLER_STREAM))
        self.pool = (ReleasedPool(_stream(cfg.seed, _POOL_STREAM), cfg.batch_workers)
                     if cfg.sampler == "released-pool" else None)
        self.epoch = 0
        self.rows: list[dict[str, Any]] = []

    # --- one epoch -------------------------------------------------------------------------------

    def run_epoch(self) -> dict[str, Any]:
        cfg, env = self.cfg, self.env
        t0 = time.perf_counter()
        sampler = (gru.GRUSampler(self.policy, self.normalizer, self.rng) if cfg.policy == "gru"
                   else Sampler(self.policy, self.normalizer, self.rng))
        if self.pool is not None:
            ro, distinct = self.pool.sample(env, sampler.act, cfg.batch_decisions)
        else:
            ro = (env.rollout(sampler, cfg.batch_episodes, epoch_seed(cfg.seed, self.epoch))
                  if cfg.batch_decisions is None else
                  batch.sample(env, sampler, cfg.batch_decisions, cfg.batch_workers,
                               epoch_seed(cfg.seed, self.epoch)))
            distinct = len(ro.episode_return)  # every episode its own stream
        t1 = time.perf_counter()
        z = self.normalizer(ro.obs)
        index = ro.step_index()
        values = self.baseline.predict(z, index)
        adv, ret = advantage_paths(cfg.advantage, ro.rewards, ro.durations, values, ro.path_start,
                                   env.gamma, cfg.lam)
        explained = 1.0 - np.var(ret - values) / np.var(ret) if np.var(ret) > 0 else 0.0
        stats = self.trpo_step(z, ro, normalize(adv))
        t2 = time.perf_counter()
        # the normaliser moves on first, so that the baseline is fitted in the coordinates in which
        # it will predict the next batch's values
        if cfg.normalize_obs:
            self.normalizer.update(ro.obs)
        baseline_loss = self.baseline.fit(self.normalizer(ro.obs), index, ret)
        t3 = time.perf_counter()
        row = dict(
            epoch=self.epoch,
            average_return=float(ro.episode_return.mean()),
            average_discounted_return=float(ro.discounted_path_returns(env.gamma).mean()),
            kl=stats.kl, entropy=stats.entropy, surrogate_before=stats.surrogate_before,
            surrogate_after=stats.surrogate_after, backtracks=stats.backtracks,
            accepted=int(stats.accepted), explained_variance=float(explained),
            baseline_loss=baseline_loss, batch_episodes=len(ro.episode_return),
            distinct_episodes=distinct,
            decisions=ro.n_decisions, truncated_episodes=ro.n_truncated,
            seconds_sim=t1 - t0, seconds_trpo=t2 - t1, seconds_baseline=t3 - t2,
            seconds_update=t3 - t1,
        )
        self.epoch += 1
        return row

    def trpo_step(self, z: np.ndarray, ro: Rollout, adv: np.ndarray) -> TRPOStats:
        """The epoch's TRPO step on the batch ``ro`` (normalised observations ``z``, normalised
        advantages ``adv``): the MLP's on its decisions, the gru's on its agent paths."""
        cfg = self.cfg
        step = dict(max_kl=cfg.max_kl, cg_iters=cfg.cg_iters, cg_damping=cfg.cg_damping,
                    backtrack_ratio=cfg.backtrack_ratio, max_backtracks=cfg.max_backtracks)
        if cfg.policy == "gru":
            paths = gru.Paths.pack(z, ro.actions, ro.path_start, self.env.n_actions)
            return gru.trpo_step(self.policy, paths, ro.actions, adv, fvp=cfg.gru_fvp,
                                 fvp_eps=cfg.gru_fvp_eps, **step)
        return trpo_step(TanhMLP(self.policy.net), z, ro.actions, adv,
                         fvp_rows=self.fvp_rows(ro.n_decisions), **step)

    def fvp_rows(self, n_decisions: int) -> np.ndarray | None:
        """The decisions of this epoch's batch on which TRPO computes Fisher-vector products:
        ``fvp_subsample`` of them, drawn afresh each epoch (None: all)."""
        cfg = self.cfg
        if cfg.fvp_subsample == 1:
            return None
        rng = np.random.default_rng(_stream(cfg.seed, _FVP_STREAM, self.epoch))
        n_rows = max(1, int(cfg.fvp_subsample * n_decisions))
        return np.sort(rng.choice(n_decisions, n_rows, replace=False))

    def train(self, on_epoch: Callable[[dict[str, Any]], None] | None = None) -> pd.DataFrame:
        """Run (or resume) up to ``cfg.epochs`` epochs; returns the progress table. A run folder
        also gets ``progress.provenance.json``: what this call ran, from which commit, on what.
        ``on_epoch`` is handed each epoch's progress row once the epoch is recorded (``train
        --tensorboard`` logs it); it sees the epochs this call trains, not those resumed from."""
        if self.out is None:
            self._epochs(on_epoch)
            return self.progress()
        t_start = time.perf_counter()
        with run_folder.writer_lock(self.out, self.param):
            state, self.rows = run_folder.start(
                self.out, self.run_config, saved_run_defaults(self.env_config,
                                                                         self.env.name),
                PROGRESS_COLUMNS, self.param, obs_dim=self.env.obs_dim,
                n_actions=self.env.n_actions,
                aliases=saved_run_aliases(self.env_config))
            if state is not None:
                self.load_state_dict(state)
            first_epoch = self.epoch
            self._epochs(on_epoch)
            run_folder.finish(self.out, self.run_config, self.cfg.seed,
                              time.perf_counter() - t_start, first_epoch, self.epoch)
        return self.progress()

    def _epochs(self, on_epoch: Callable[[dict[str, Any]], None] | None) -> None:
        for _ in progress(range(self.epoch, self.cfg.epochs), f"train {self.cfg.env}",
                          total=self.cfg.epochs - self.epoch):
            t0 = time.perf_counter()
            row = self.run_epoch()
            row["seconds"] = time.perf_counter() - t0
            self.rows.append(row)
            if self.out is not None:
                run_folder.record_epoch(self.out, row, PROGRESS_COLUMNS, self.state_dict(),
                                        self.cfg.epochs)
            if on_epoch is not None:
                on_epoch(row)

    def progress(self) -> pd.DataFrame:
        return pd.DataFrame(self.rows, columns=PROGRESS_COLUMNS)

    # --- checkpoints -----------------------------------------------------------------------------

    def state_dict(self) -> dict[str, Any]:
        pool = {} if self.pool is None else {"pool_offsets": torch.from_numpy(self.pool.offsets)}
        return {
            "epoch": self.epoch,
            "policy": self.policy.state_dict(),
            "baseline": self.baseline.state_dict(),
            "normalizer": self.normalizer.state_dict(),
            "sampler_rng": self.rng.bit_generator.state,  # saved as JSON
            "torch_rng": torch.get_rng_state(),
            "run_config": self.run_config,
            **pool,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.epoch = int(state["epoch"])
        self.policy.load_state_dict(state["policy"])
        self.baseline.load_state_dict(state["baseline"])
        self.normalizer.load_state_dict(state["normalizer"])
        self.rng.bit_generator.state = state["sampler_rng"]
        torch.set_rng_state(state["torch_rng"])
        if self.pool is not None:
            self.pool.offsets = state["pool_offsets"].numpy().astype(np.int64)


