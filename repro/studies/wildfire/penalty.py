"""Which crowding penalty gives the paper's behaviour (claims C6, C7): the behaviour study
(:mod:`repro.studies.wildfire.behaviour`) over penalties, each policy measured as the authors
measured theirs and as the suite does, and the penalty whose policies come closest to the paper's
six numbers.

Why: the paper's behaviour numbers come from ONE policy, trained 3,000 epochs on ED in a run named
for a high crowding penalty (``..._dt_-1.000_high_coll_pen``, 2017-04-26), which predates the
commit that set the released simulator's -20 (2017-05-16; the simulator of 2017-04-22 has -1), so
its penalty is unknown. The simulator versions differ in nothing else (``SIM_VERSIONS``): penalty
1 is the 2017-04-22 simulator, penalty 20 the released one.

Every penalty P in ``penalties`` trains ``seeds`` policies on ED with r_pen = -P (run folders
``<runs-dir>/wildfire-penalty/<scale>/pen<P>-ed-seed<s>``) and measures each twice:

- *as the authors did* (their ``policy_intuitions.jl`` on 500 sampled episodes of one policy,
  columns ``authors_*``): at a live fire = observed distance to the closest fire below 1e-7 and
  its status 1; ``hold_alone`` = P(hold | at a live fire, interest party 1), ``hold_shared`` =
  P(hold | at a live fire, party above 1); ``fly_rank_k`` = share of the non-hold actions that
  target the k-th closest observed fire; ``closest_cluster`` = ``fly_rank_1 + 2 + 3`` (the three
  closest observed fires, which the paper calls the closest cluster). ``authors_episodes`` sampled
  episodes per policy, each policy on its own;
- *as the suite does* (:func:`repro.studies.wildfire.behaviour.frequency_counts`, on
  ``test_episodes`` episodes; columns without prefix), with the flowchart's ADR on the same
  episodes under that penalty (C7's ``flowchart_worse``).

Outputs: ``wildfire_penalty.csv``, one row per policy; ``wildfire_penalty_fit.csv``, one row per
(penalty, definitions): the mean over the penalty's policies of each of the six numbers, their
root-mean-square and largest distance to the paper's, and ``best`` for the penalty with the
smallest RMS distance (one parameter fitted on six numbers: the fit says which penalty, not that
the numbers reproduce).
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

from repro.core.config import add_config_arguments
from repro.core.rollout import Rollout
from repro.envs.wildfire import RELEASED_VERSION, WildfireConfig, make_env
from repro.envs.wildfire.params import DIST, INTEREST, STATUS, fire_blocks
from repro.envs.wildfire.policies import FlowchartPolicy
from repro.learn.config import add_study_learner_arguments, learner_name, learner_suffix
from repro.paper import BEHAVIOUR_FREQUENCIES
from repro.runs.provenance import provenance
from repro.runs.results import write_result
from repro.studies.kit.options import Command, Folders, add_common
from repro.studies.kit.sweep import TrainJob, add_sweep_arguments, policy_stream, run_sweep
from repro.studies.wildfire.study import (BehaviourConfig, adr, behaviour_config, counted,
                                          evaluate, frequency_counts, shares)

AUTHORS_AT_FIRE = 1e-7
"""The authors' script's distance below which a UAV is at its closest fire."""
SIX = tuple(BEHAVIOUR_FREQUENCIES)
"""The paper's six behaviour numbers (C6), in its order."""

# Independent child streams of the root seed.
_TEST_ENV_STREAM, _POLICY_STREAM, _AUTHORS_ENV_STREAM, _AUTHORS_POLICY_STREAM = 0, 1, 2, 3


@dataclass(frozen=True)
class PenaltyConfig(BehaviourConfig):
    """The behaviour study's sizes, over crowding penalties, on the released simulator with each
    penalty (the versions differ in nothing else)."""

    penalties: tuple[float, ...] = (1.0, 2.0, 5.0, 10.0, 20.0)
    """Crowding penalties (r_pen = -penalty per crowding UAV; 2017-04-22: 1, released: 20)."""
    authors_episodes: int = 500
    """Sampled episodes per policy of the authors' evaluation (their script: 500)."""

    SCALES: ClassVar[dict] = {
        **BehaviourConfig.SCALES,
        "smoke": dict(BehaviourConfig.SCALES["smoke"], penalties=(1.0, 20.0),
                      authors_episodes=20),
    }

    def validate(self) -> None:
        super().validate()
        self.check(len(self.penalties) >= 1 and min(self.penalties) >= 0, "penalties",
                   "one or more numbers >= 0")
        self.check(len(set(self.penalties)) == len(self.penalties), "penalties", "distinct")
        self.check(self.sim_version == RELEASED_VERSION, "sim_version",
                   f"{RELEASED_VERSION} (the penalty is the versions' only difference)")
        self.check(self.authors_episodes >= 1, "authors_episodes", "an integer >= 1")

    def penalty_env(self, penalty: float) -> WildfireConfig:
        """The ED simulator with crowding penalty ``penalty``."""
        return dataclasses.replace(self.env(), r_pen=-float(penalty))


def authors_counts(rollout: Rollout, env: WildfireConfig) -> dict[str, int]:
    """The counts behind the authors' frequencies (module docstring): events and their
    conditions, as :func:`repro.studies.wildfire.behaviour.frequency_counts` gives ours."""
    block, act, k = fire_blocks(rollout.obs, env.n_observed), rollout.actions, env.n_observed
    at_live = (block[:, 0, DIST] < AUTHORS_AT_FIRE) & (block[:, 0, STATUS] == 1)
    alone = at_live & (block[:, 0, INTEREST] == 1)
    shared = at_live & (block[:, 0, INTEREST] > 1)
    hold, fly = act == k, act != k
    out = dict(hold_shared_events=int((hold & shared).sum()), n_shared=int(shared.sum()),
               hold_alone_events=int((hold & alone).sum()), n_alone=int(alone.sum()),
               n_fly=int(fly.sum()))
    out.update({f"fly_rank_{r + 1}_events": int((act == r).sum()) for r in range(k)})
    return out


def authors_shares(counts: dict[str, int]) -> dict[str, float]:
    """The authors' six numbers from :func:`authors_counts`, prefixed ``authors_``."""
    out = shares(counts)
    out["closest_cluster"] = sum(out[f"fly_rank_{r}"] for r in (1, 2, 3))
    return {f"authors_{key}": out[key] for key in SIX}


def make_jobs(cfg: PenaltyConfig, scale: str, seed: int) -> list[TrainJob]:
    return [TrainJob(f"pen{p:g}-ed-seed{s}", cfg.train_config(scale, s), cfg.penalty_env(p))
            for p in cfg.penalties for s in range(seed, seed + cfg.seeds)]


def _env_seed(seed: int, stream: int) -> int:
    return int(np.random.SeedSequence(seed, spawn_key=(stream,)).generate_state(1)[0])


def measure_policy(cfg: PenaltyConfig, job: TrainJob, folder: Path, seed: int,
                   flowchart_adr: float) -> dict:
    """One policy's row: its numbers by both definitions, its ADR, C7's ratio."""
    from repro.learn.trained_policy import policy_from_state
    from repro.runs.run_folder import CHECKPOINT, load_checkpoint

    env_cfg = job.env_config
    env = make_env(env_cfg)
    state = load_checkpoint(folder / CHECKPOINT, "--runs-dir", obs_dim=env.obs_dim,
                            n_actions=env.n_actions)

    def policy(stream: int):
        return policy_from_state(state, np.random.default_rng(policy_stream(seed, stream,
                                                                            job.name)))

    ours, rollout = counted(env, policy(_POLICY_STREAM), cfg.test_episodes,
                            _env_seed(seed, _TEST_ENV_STREAM),
                            lambda batch: frequency_counts(batch, env_cfg))
    theirs, _ = counted(env, policy(_AUTHORS_POLICY_STREAM), cfg.authors_episodes,
                        _env_seed(seed, _AUTHORS_ENV_STREAM),
                        lambda batch: authors_counts(batch, env_cfg))
    learned_adr, learned_sem = adr(rollout, env.gamma)
    return dict(penalty=-env_cfg.r_pen, train_seed=job.train.seed, epochs=job.train.epochs,
                learner=learner_name(job.train), test_episodes=cfg.test_episodes,
                authors_episodes=cfg.authors_episodes, max_decisions=cfg.max_decisions or 0,
                test_truncated=rollout.n_truncated, **authors_shares(theirs), **shares(ours),
                adr_learned=learned_adr, adr_learned_sem=learned_sem,
                adr_flowchart=flowchart_adr, flowchart_worse=1.0 - flowchart_adr / learned_adr,
                run=job.name)


def flowchart_adr(cfg: PenaltyConfig, penalty: float, seed: int) -> float:
    """The flowchart policy's ADR on the test episodes under ``penalty``."""
    env = make_env(cfg.penalty_env(penalty))
    flowchart = FlowchartPolicy(
        np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_POLICY_STREAM, 0))),
        n_observed=cfg.env().n_observed)
    rollout = evaluate(env, flowchart, cfg.test_episodes, _env_seed(seed, _TEST_ENV_STREAM),
                       keep_obs=False)
    return adr(rollout, env.gamma)[0]


def fit(table: pd.DataFrame) -> pd.DataFrame:
    """Per (penalty, definitions) the mean of each of the six numbers over its policies and the
    distances to the paper's; ``best`` marks the closest penalty of each definition."""
    paper = np.array([BEHAVIOUR_FREQUENCIES[k] for k in SIX])
    rows = []
    for definitions, prefix in (("authors", "authors_"), ("suite", "")):
        for penalty, grp in table.groupby("penalty", sort=True):
            means = np.array([grp[prefix + k].mean() for k in SIX])
            gap = means - paper
            rows.append(dict(definitions=definitions, penalty=penalty, policies=len(grp),
                             **dict(zip(SIX, means)),
                             rms_distance=float(np.sqrt(np.nanmean(gap ** 2))),
                             max_distance=float(np.nanmax(np.abs(gap)))))
    out = pd.DataFrame(rows)
    best = out.groupby("definitions").rms_distance.transform("min")
    out["best"] = out.rms_distance == best
    return out


FLAGS = ("penalties", "seeds", "epochs", "test_episodes", "authors_episodes", "max_decisions")
"""The PenaltyConfig fields the study takes as flags, besides the learner and its batch sizes."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p, figures=False)
    add_sweep_arguments(p)
    add_config_arguments(p, PenaltyConfig, FLAGS)
    add_study_learner_arguments(p, "wildfire_penalty_suite*")


def configure(args: argparse.Namespace) -> Command[PenaltyConfig]:
    return Command.of(args, behaviour_config(PenaltyConfig, args))


def run(cmd: Command[PenaltyConfig], folders: Folders) -> int:
    cfg, scale, seed = cmd.study, folders.scale, cmd.seed
    results = folders.open_results()
    stem = "_".join(("wildfire_penalty", *learner_suffix(cfg.learner)))
    runs = folders.run_root(stem.replace("_", "-"), scale)
    jobs = make_jobs(cfg, scale, seed)
    t0 = time.perf_counter()
    done = run_sweep(jobs, runs, cmd.workers)
    flow = {p: flowchart_adr(cfg, p, seed) for p in cfg.penalties}
    table = pd.DataFrame([measure_policy(cfg, job, folder, seed, flow[-job.env_config.r_pen])
                          for job, folder in zip(jobs, done)])
    prov = provenance(dataclasses.asdict(cfg), command="wildfire-penalty", scale=scale,
                      seed=seed, wall_seconds=time.perf_counter() - t0,
                      extra=dict(runs_dir=str(runs), paper=dict(BEHAVIOUR_FREQUENCIES)))
    write_result(results / f"{stem}.csv", table, prov)
    fitted = fit(table)
    write_result(results / f"{stem}_fit.csv", fitted, prov)
    print(fitted.to_string(index=False))
    return 0
