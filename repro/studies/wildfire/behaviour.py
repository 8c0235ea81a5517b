"""What a long ED-trained wildfire policy does (claim C6) and how the flowchart that encodes it
compares (claim C7); paper section "Wildfire, Results", Fig. "appxpolicy".

Policies are trained on the ED simulator (PS-TRPO + M-GAE through the sweep runner, checkpointed
under ``--runs-dir``/wildfire-behaviour/<scale>/). Each trained policy is then run, sampling its
actions as in training, on ``test_episodes`` ED episodes, and every recorded (observation o, action
a) pair of every agent is classified (docs/semantics.md section 6.3). With the observation layout of
section 3.6, fire j = the j-th closest observed fire, d_j its distance, s_j its status, I_j its
interest party size:

- *at a live fire*: d_1 < OBSERVED_AT_FIRE_TOL and s_1 = 1 (the UAV sits on its closest fire,
  which burns);
- *other interest*: I_1 - 1 >= 1. The observer is in the interest party of the fire it sits at (it
  flew to it or held at it, see ``repro.envs.wildfire.policies``), so I_1 - 1 UAVs are others;
- ``hold_shared`` = P(a = hold | at a live fire, other interest);
- ``hold_alone``  = P(a = hold | at a live fire, no other interest);
- ``fly_rank_k``  = P(a = k-th closest fire | a is a fly action), k = 1..5, over every decision;
- ``closest_cluster`` = P(the target fire lies in the cluster of the UAV's closest fire | a is a
  fly action). The target is identified by ranking all nine fires by distance from the UAV's
  observed position, as the engine does; clusters are the blocks of three of ``fire_positions``.

*Stay flights*: a fly action to a fire closer than OBSERVED_AT_FIRE_TOL, that is, to the fire the
UAV is at. It takes no time (in ED; a UAV cut off just short of the fire flies the rest, under
0.07 s), so the UAV decides again after the 1e-5 s latency. docs/semantics.md section 6.3 counts
them among the fly actions, as above. Learned ED policies make many (about half of the decisions of
the quick-scale policy, 92% of a paper-scale run's at epoch 316), which swamps ``fly_rank_1`` and
``hold_alone``. So every frequency is also given without them (suffix ``_ex_stay``), and
``stay_flight`` is their share of all decisions. The flowchart's own frequencies are measured the
same way (``wildfire_behaviour_flowchart.csv``): its ``_ex_stay`` values are the paper's policy, as
the flowchart encodes it, without stay flights.

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
from pathlib import Path

import numpy as np
import pandas as pd

from repro.core.config import add_config_arguments
from repro.envs.wildfire import make_env
from repro.envs.wildfire.policies import FlowchartPolicy
from repro.learn.config import add_study_learner_arguments
from repro.paper import BEHAVIOUR_FREQUENCIES, FLOWCHART_WORSE
from repro.runs.provenance import provenance
from repro.runs.results import write_result
from repro.studies.kit.options import Command, Folders, add_common
from repro.studies.kit.sweep import TrainJob, add_sweep_arguments, policy_stream, run_sweep
from repro.studies.wildfire.study import (BehaviourConfig, adr, behaviour_config, counted,
                                          frequency_counts, shares)

PAPER = dict(**BEHAVIOUR_FREQUENCIES, flowchart_worse=FLOWCHART_WORSE)
"""The paper's numbers (section "Wildfire, Results", :mod:`repro.paper`) as the sidecar records
them; fly_rank_4/5 are not given."""
# Independent child streams of the root seed.
_TEST_ENV_STREAM, _POLICY_STREAM = 0, 1


def make_jobs(cfg: BehaviourConfig, scale: str, seed: int) -> list[TrainJob]:
    return [TrainJob(f"ed-seed{s}", cfg.train_config(scale, s), cfg.env())
            for s in range(seed, seed + cfg.seeds)]


def measure(cfg: BehaviourConfig, jobs: list[TrainJob], folders: list[Path],
            seed: int) -> tuple[pd.DataFrame, pd.DataFrame]:
    """One row per trained policy: its C6 frequencies, its ADR and the flowchart's on the same
    episodes; and one row of the flowchart's own frequencies on those episodes."""
    from repro.learn.config import learner_name
    from repro.learn.trained_policy import policy_from_state
    from repro.runs.run_folder import CHECKPOINT, load_checkpoint

    env_cfg = cfg.env()
    env = make_env(env_cfg)
    env_seed = int(np.random.SeedSequence(seed, spawn_key=(_TEST_ENV_STREAM,)).generate_state(1)[0])


    def observe(policy) -> tuple[dict[str, float], float, float, int]:
        """The policy's frequencies (counted per test batch, so that observations need not be
        kept), ADR with its standard error, and the episodes cut at the decision limit."""
        total, rollout = counted(env, policy, cfg.test_episodes, env_seed,
                                 lambda batch: frequency_counts(batch, env_cfg))
        return shares(total), *adr(rollout, env.gamma), rollout.n_truncated

    flowchart = FlowchartPolicy(
        np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_POLICY_STREAM, 0))),
        n_observed=env_cfg.n_observed)
    flow_shares, flow_adr, flow_sem, _ = observe(flowchart)
    rows = []
    for job, folder in zip(jobs, folders):  # each policy's stream keyed by its run
        policy = policy_from_state(load_checkpoint(folder / CHECKPOINT, "--runs-dir",
                                                   obs_dim=env.obs_dim, n_actions=env.n_actions),
                                   np.random.default_rng(policy_stream(seed, _POLICY_STREAM,
                                                                       job.name)))
        learned, learned_adr, learned_sem, cut = observe(policy)
        rows.append(dict(train_seed=job.train.seed, epochs=job.train.epochs,
                         learner=learner_name(job.train), r_pen=env_cfg.r_pen,
                         batch_decisions=job.train.batch_decisions or 0,
                         batch_episodes=job.train.batch_episodes or 0,
                         test_episodes=cfg.test_episodes,
                         max_decisions=cfg.max_decisions or 0, test_truncated=cut,
                         **learned, adr_learned=learned_adr,
                         adr_learned_sem=learned_sem, adr_flowchart=flow_adr,
                         adr_flowchart_sem=flow_sem,
                         flowchart_worse=1.0 - flow_adr / learned_adr, run=job.name))
    flow_row = dict(test_episodes=cfg.test_episodes, **flow_shares, adr_flowchart=flow_adr,
                    adr_flowchart_sem=flow_sem)
    return pd.DataFrame(rows), pd.DataFrame([flow_row])


FLAGS = ("seeds", "epochs", "sim_version", "test_episodes", "max_decisions")
"""The BehaviourConfig fields the study takes as flags, besides the learner and its batch sizes
(:func:`repro.learn.config.add_study_learner_arguments`)."""
VARIANTS = ("sim_version",)
"""The option that chooses the study (``*_20170422``), not its settings
(:func:`repro.studies.kit.options.scale_departures`)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p, figures=False)
    add_sweep_arguments(p)
    add_config_arguments(p, BehaviourConfig, FLAGS)
    add_study_learner_arguments(p, "wildfire_behaviour_suite*")


def configure(args: argparse.Namespace) -> Command[BehaviourConfig]:
    return Command.of(args, behaviour_config(BehaviourConfig, args))


def run(cmd: Command[BehaviourConfig], folders: Folders) -> int:
    cfg, scale, seed = cmd.study, folders.scale, cmd.seed
    results = folders.open_results()
    runs = folders.run_root(cfg.name.replace("_", "-"), scale)
    jobs = make_jobs(cfg, scale, seed)
    t0 = time.perf_counter()
    done = run_sweep(jobs, runs, cmd.workers)
    table, flowchart = measure(cfg, jobs, done, seed)
    prov = provenance(dataclasses.asdict(cfg), command="wildfire-behaviour", scale=scale,
                      seed=seed, wall_seconds=time.perf_counter() - t0,
                      extra=dict(runs_dir=str(runs), paper=PAPER))
    write_result(results / f"{cfg.name}.csv", table, prov)
    write_result(results / f"{cfg.name}_flowchart.csv", flowchart, prov)
    print(table.drop(columns=["run"]).T.to_string())
    return 0
