"""Which observation entries C9's failing policies depend on (docs/semantics.md section 6.14).

With the released quirk Q3, a fire that is out keeps reporting a health that drains below zero (to
about -343 by an episode's end), and the time since the current action (the sojourn) reaches a
hundred seconds; the authors' learner feeds both raw into its tanh units. This driver takes the
policies of a transfer study's C9 pair and ED (training nothing that the study has not trained:
they are ``fig-transfer``'s runs) and tests each on the ED test simulator with one group of inputs
clamped at test time (:data:`CLAMPS`): health to >= 0 (what the corrected simulator reports), the
sojourn to <= 10 s (the linear baseline's clip), or both. A policy whose ADR moves when an input
is clamped depends on that input's out-of-range values.

Every variant of a policy plays the same episodes with the same action stream, so a change is the
clamp's, not noise between episode sets. Outputs: ``c9_inputs.csv`` (per policy and clamp: ADR,
its change from the unclamped policy, and how often the clamp changed an input) and
``c9_inputs_summary.csv`` (per training simulator and clamp: mean change over policies with its
95% bootstrap CI).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from typing import Callable

import numpy as np
import pandas as pd

from repro.core.config import add_config_arguments
from repro.core.rollout import DecisionBatch, Policy
from repro.envs.wildfire import FIGURE_VERSION, make_env
from repro.envs.wildfire.params import FIRES, HEALTH, OBS_PER_FIRE, SOJOURN
from repro.learn.config import learner_stem
from repro.runs.provenance import provenance
from repro.runs.results import write_result
from repro.runs.stats import bootstrap_ci
from repro.studies.kit.options import Command, Folders
from repro.studies.kit.sweep import policy_stream, run_sweep
from repro.studies.transfer.study import (TransferConfig, add_size_arguments, make_jobs,
                                          runs_folder, study_config, test_env_seed)
from repro.studies.wildfire.study import adr, evaluate

NAME = "c9_inputs"
"""Stem of the result files."""
_POLICY_STREAM, _BOOT_STREAM = 6, 7
"""Children of the root seed (the transfer study and its companions use 0-5)."""


def clamp_health(obs: np.ndarray, n_observed: int) -> None:
    """Every observed fire's health to >= 0, in place."""
    cols = FIRES + HEALTH + OBS_PER_FIRE * np.arange(n_observed)
    obs[:, cols] = np.maximum(obs[:, cols], 0.0)


def clamp_sojourn(obs: np.ndarray, n_observed: int) -> None:
    """The sojourn (time since the current action started) to <= 10 s, in place."""
    obs[:, SOJOURN] = np.minimum(obs[:, SOJOURN], 10.0)


CLAMPS: dict[str, tuple[Callable[[np.ndarray, int], None], ...]] = {
    "none": (),
    "health >= 0": (clamp_health,),
    "sojourn <= 10 s": (clamp_sojourn,),
    "both": (clamp_health, clamp_sojourn),
}
"""Input groups clamped at test time."""


class Clamped:
    """``policy`` acting on observations with ``clamps`` applied; counts the decisions whose
    observation a clamp changed."""

    def __init__(self, policy: Policy, clamps: tuple, n_observed: int):
        self.policy, self.clamps, self.n_observed = policy, clamps, n_observed
        self.decisions = self.changed = 0

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        obs = batch.obs.copy()
        for clamp in self.clamps:
            clamp(obs, self.n_observed)
        self.decisions += len(obs)
        self.changed += int((obs != batch.obs).any(axis=1).sum())
        return self.policy(dataclasses.replace(batch, obs=obs))


def score(env_cfg, checkpoint, clamps: tuple, episodes: int, env_seed: int,
          stream: np.random.SeedSequence) -> tuple[float, float]:
    """ADR of a policy with ``clamps`` and the share of its decisions they changed."""
    from repro.runs.run_folder import load_checkpoint
    from repro.learn.trained_policy import policy_from_state

    env = make_env(env_cfg)
    state = load_checkpoint(checkpoint, "--runs-dir", obs_dim=env.obs_dim, n_actions=env.n_actions)
    policy = Clamped(policy_from_state(state, np.random.default_rng(stream)), clamps,
                     env_cfg.n_observed)
    rollout = evaluate(env, policy, episodes, env_seed, keep_obs=False)
    return adr(rollout, env.gamma)[0], policy.changed / max(policy.decisions, 1)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_size_arguments(p, "c9_inputs_suite*")
    add_config_arguments(p, TransferConfig, ("sim_version",),
                         defaults=dict(sim_version=FIGURE_VERSION))


def configure(args: argparse.Namespace) -> Command[TransferConfig]:
    cfg = study_config(args, sim_version=getattr(args, "sim_version", FIGURE_VERSION))
    return Command.of(args, dataclasses.replace(cfg, only=("ED", *cfg.variant_pair()[::-1])))


def run(cmd: Command[TransferConfig], folders: Folders) -> int:
    from repro.runs.run_folder import CHECKPOINT

    cfg, scale, seed = cmd.study, folders.scale, cmd.seed
    results, _ = folders.open()
    labelled = make_jobs(cfg, scale, seed)
    t0 = time.perf_counter()
    done = run_sweep([job for _, job in labelled], runs_folder(folders, cfg), cmd.workers)
    env_seed, test = test_env_seed(seed), cfg.test_simulator()
    rows = []
    for (label, job), folder in zip(labelled, done):
        stream = policy_stream(seed, _POLICY_STREAM, job.name)
        for name, clamps in CLAMPS.items():
            value, changed = score(test, folder / CHECKPOINT, clamps, cfg.test_episodes,
                                   env_seed, stream)
            rows.append(dict(simulator=label, train_seed=job.train.seed, clamp=name,
                             adr_ed=value, changed_share=changed, run=job.name))
    table = pd.DataFrame(rows)
    table["change"] = table.adr_ed - table.groupby("run").adr_ed.transform("first")
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_BOOT_STREAM,)))
    summary = []
    for (label, name), g in table.groupby(["simulator", "clamp"], sort=False):
        point, lo, hi = bootstrap_ci(g.change.to_numpy(), np.mean, n_boot=cfg.n_boot, rng=rng)
        summary.append(dict(simulator=label, clamp=name, n_policies=len(g),
                            adr_ed=float(g.adr_ed.mean()), change=point, ci_low=lo, ci_high=hi,
                            changed_share=float(g.changed_share.mean())))
    summary = pd.DataFrame(summary)
    stem = learner_stem(NAME, cfg.learner)
    prov = provenance(dataclasses.asdict(cfg), command="c9-inputs", scale=scale,
                      seed=seed, wall_seconds=time.perf_counter() - t0,
                      extra=dict(study=cfg.name))
    write_result(results / f"{stem}.csv", table, prov)
    write_result(results / f"{stem}_summary.csv", summary, prov)
    print(summary.to_string(index=False))
    return 0
