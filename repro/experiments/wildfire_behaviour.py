"""What a long ED-trained wildfire policy does (claim C6) and how the flowchart that encodes it
compares (claim C7); paper section "Wildfire, Results", Fig. "appxpolicy".

Policies are trained on the ED simulator (PS-TRPO + M-GAE through the sweep runner, checkpointed
under ``--runs-dir``/wildfire-behaviour/<scale>/). Each trained policy is then run, sampling its
actions as in training, on ``test_episodes`` ED episodes, and every recorded (observation o,
action a) pair of every agent is classified. With the observation layout of SPEC 3, fire j = the
j-th closest observed fire, d_j its distance, s_j its status, I_j its interest party size:

- *at a live fire*: d_1 < AT_FIRE_TOL and s_1 = 1 (the UAV sits on its closest fire, which burns);
- *other interest*: I_1 - 1 >= 1. The observer is in the interest party of the fire it sits at (it
  flew to it or held at it, see ``repro.envs.wildfire.policies``), so I_1 - 1 UAVs are others;
- ``hold_shared`` = P(a = hold | at a live fire, other interest);
- ``hold_alone``  = P(a = hold | at a live fire, no other interest);
- ``fly_rank_k``  = P(a = k-th closest fire | a is a fly action), k = 1..5, over every decision;
- ``closest_cluster`` = P(the target fire lies in the cluster of the UAV's closest fire | a is a
  fly action). The target is identified by ranking all nine fires by distance from the UAV's
  observed position, as the engine does; clusters are the blocks of three of ``fire_positions``.

C7: the ``flowchart`` policy (``repro.envs.wildfire.policies.FlowchartPolicy``, the paper's
probabilities) and each learned policy are tested on the same ED episodes;
``flowchart_worse`` = 1 - ADR(flowchart) / ADR(learned) (paper: 0.28).

Applying the same classification to the flowchart policy's own decisions must give back its
probabilities, which is how the tests check these definitions.
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

from repro.cli import add_common
from repro.core.config import for_scale
from repro.core.errors import require
from repro.core.io import check_writable_dir, provenance, write_result
from repro.core.rollout import Rollout
from repro.envs.wildfire import WildfireConfig, fire_positions, make_env
from repro.envs.wildfire.params import OBS_PER_FIRE
from repro.envs.wildfire.policies import AT_FIRE_TOL, FlowchartPolicy
from repro.experiments.sweep import (TrainJob, add_sweep_arguments, check_sweep_arguments,
                                     run_sweep)
from repro.experiments.wildfire_eval import adr, evaluate

PAPER = dict(hold_shared=0.27, hold_alone=0.84, fly_rank_1=0.15, fly_rank_2=0.15, fly_rank_3=0.68,
             closest_cluster=0.98, flowchart_worse=0.28)
"""The paper's numbers (section "Wildfire, Results"); fly_rank_4/5 are not given."""
FIRES_PER_CLUSTER = 3

# Independent child streams of the root seed.
_TEST_ENV_STREAM, _POLICY_STREAM = 0, 1


@dataclass(frozen=True)
class BehaviourConfig:
    """Sizes of the behaviour study (the ED simulator and its semantics never change)."""

    seeds: int = 1
    """Policies trained from scratch (the paper examined one). Long ED runs can drift into
    policies that re-decide at a fire many times per second (fly to the fire they are at), which
    makes their epochs up to ten times slower; hence one at quick scale."""
    epochs: int = 300
    """Training epochs per policy (paper: 3,000)."""
    batch_episodes: int = 200
    """Training episodes per epoch (paper: 600 to 1,200)."""
    test_episodes: int = 1000
    """ED episodes on which frequencies and ADRs are measured."""

    SCALES: ClassVar[dict] = {
        "smoke": dict(seeds=1, epochs=2, batch_episodes=8, test_episodes=20),
        "quick": {},
        "paper": dict(seeds=3, epochs=3000, batch_episodes=600, test_episodes=10000),
    }

    def validate(self) -> None:
        require(self.seeds >= 1, "--seeds", "an integer >= 1", self.seeds)
        require(self.epochs >= 1, "--epochs", "an integer >= 1", self.epochs)
        require(self.batch_episodes >= 1, "--batch-episodes", "an integer >= 1",
                self.batch_episodes)
        require(self.test_episodes >= 1, "--test-episodes", "an integer >= 1", self.test_episodes)


def frequency_counts(rollout: Rollout, env: WildfireConfig) -> dict[str, int]:
    """The counts behind the C6 frequencies: for each, the decisions where its event happened
    (``<name>_events``) out of those where its condition held (``n_shared``, ``n_alone``,
    ``n_fly``). Counts of separate batches add up."""
    obs, act, k = rollout.obs, rollout.actions, env.n_observed
    block = obs[:, 2:2 + OBS_PER_FIRE * k].reshape(len(obs), k, OBS_PER_FIRE)
    at_live = (block[:, 0, 0] < AT_FIRE_TOL) & (block[:, 0, 3] > 0.5)
    shared = block[:, 0, 2] - 1 >= 1
    hold = act == k
    fly = ~hold
    dist = np.linalg.norm(obs[:, None, :2] - fire_positions(env)[None], axis=2)
    order = np.argsort(dist, axis=1, kind="stable")
    rows = np.arange(len(obs))
    target_cluster = order[rows, np.minimum(act, k - 1)] // FIRES_PER_CLUSTER
    nearest_cluster = order[:, 0] // FIRES_PER_CLUSTER
    out = dict(hold_shared_events=int((hold & at_live & shared).sum()),
               hold_alone_events=int((hold & at_live & ~shared).sum()))
    out.update({f"fly_rank_{r + 1}_events": int((act == r).sum()) for r in range(k)})
    out["closest_cluster_events"] = int(((target_cluster == nearest_cluster) & fly).sum())
    out.update(n_shared=int((at_live & shared).sum()), n_alone=int((at_live & ~shared).sum()),
               n_fly=int(fly.sum()), n_decisions=len(act))
    return out


def shares(counts: dict[str, int]) -> dict[str, float]:
    """The C6 frequencies of the module docstring from :func:`frequency_counts` (NaN where a
    condition never occurs), with the number of decisions behind each conditional."""
    given = dict(hold_shared="n_shared", hold_alone="n_alone", closest_cluster="n_fly")
    out = {}
    for key in counts:
        if key.endswith("_events"):
            name = key[:-len("_events")]
            n = counts[given.get(name, "n_fly")]
            out[name] = counts[key] / n if n else float("nan")
    out.update({k: v for k, v in counts.items() if k.startswith("n_")})
    return out


def frequencies(rollout: Rollout, env: WildfireConfig) -> dict[str, float]:
    """The C6 frequencies of one rollout (see :func:`shares`)."""
    return shares(frequency_counts(rollout, env))


def make_jobs(cfg: BehaviourConfig, scale: str, seed: int) -> list[TrainJob]:
    from repro.learn.trainer import train_config

    return [TrainJob(f"ed-seed{s}", train_config(scale, "wildfire", seed=s, epochs=cfg.epochs,
                                                 batch_episodes=cfg.batch_episodes),
                     WildfireConfig())
            for s in range(seed, seed + cfg.seeds)]


def measure(cfg: BehaviourConfig, jobs: list[TrainJob], folders: list[Path],
            seed: int) -> pd.DataFrame:
    """One row per trained policy: its C6 frequencies, its ADR and the flowchart's on the same
    episodes."""
    from repro.learn.trainer import CHECKPOINT, policy_from_checkpoint

    env_cfg = WildfireConfig()
    env = make_env(env_cfg)
    env_seed = int(np.random.SeedSequence(seed, spawn_key=(_TEST_ENV_STREAM,)).generate_state(1)[0])

    def rng(i: int) -> np.random.Generator:
        return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_POLICY_STREAM, i)))

    flow_adr, flow_sem = adr(evaluate(env, FlowchartPolicy(rng(0), n_observed=env_cfg.n_observed),
                                      cfg.test_episodes, env_seed, keep_obs=False), env.gamma)
    rows = []
    for i, (job, folder) in enumerate(zip(jobs, folders), start=1):
        counts: list[dict[str, int]] = []  # per test batch, so that observations need not be kept
        rollout = evaluate(env, policy_from_checkpoint(folder / CHECKPOINT, rng(i)),
                           cfg.test_episodes, env_seed, keep_obs=False,
                           on_batch=lambda batch: counts.append(frequency_counts(batch, env_cfg)))
        learned_adr, learned_sem = adr(rollout, env.gamma)
        total = {key: sum(c[key] for c in counts) for key in counts[0]}
        rows.append(dict(train_seed=job.train.seed, epochs=job.train.epochs,
                         batch_episodes=job.train.batch_episodes, test_episodes=cfg.test_episodes,
                         **shares(total), adr_learned=learned_adr,
                         adr_learned_sem=learned_sem, adr_flowchart=flow_adr,
                         adr_flowchart_sem=flow_sem,
                         flowchart_worse=1.0 - flow_adr / learned_adr, run=job.name))
    return pd.DataFrame(rows)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p)
    add_sweep_arguments(p)
    p.add_argument("--seeds", type=int, help="policies trained (paper: 1)")
    p.add_argument("--epochs", type=int, help="training epochs per policy (paper: 3000)")
    p.add_argument("--batch-episodes", type=int, help="training episodes per epoch (paper: 600)")
    p.add_argument("--test-episodes", type=int, help="ED episodes measured per policy")


def run(args: argparse.Namespace) -> int:
    cfg = for_scale(BehaviourConfig, args.scale, seeds=args.seeds, epochs=args.epochs,
                    batch_episodes=args.batch_episodes, test_episodes=args.test_episodes)
    cfg.validate()
    check_sweep_arguments(args)
    results = check_writable_dir(args.results_dir, "--results-dir")
    runs = check_writable_dir(Path(args.runs_dir) / "wildfire-behaviour" / args.scale,
                              "--runs-dir")
    jobs = make_jobs(cfg, args.scale, args.seed)
    t0 = time.perf_counter()
    folders = run_sweep(jobs, runs, n_jobs=args.n_jobs, scheduler=args.scheduler)
    table = measure(cfg, jobs, folders, args.seed)
    prov = provenance(dataclasses.asdict(cfg), command="wildfire-behaviour", scale=args.scale,
                      seed=args.seed, wall_seconds=time.perf_counter() - t0,
                      extra=dict(runs_dir=str(runs), paper=PAPER))
    write_result(results / "wildfire_behaviour.csv", table, prov)
    print(table.drop(columns=["run"]).T.to_string())
    return 0
