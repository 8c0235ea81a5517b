"""``wildfire-heuristics``: the heuristic policies' ADR on the transfer study's ED test episodes,
the baselines beside the learned policies of C8 and C9.

Every heuristic (random, nearest, flowchart) plays the very episodes the transfer study tests its
trained policies on (the same test simulator, episode count and environment seed), under the
released and the corrected semantics. A trained policy that does no better than ``nearest`` has
learned little that a one-line rule does not know. Writes ``wildfire_heuristics.csv``: one row per
semantics and policy, ADR with its standard error over paths.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
import pandas as pd

from repro.core.config import add_config_arguments, for_scale, given_fields
from repro.envs.wildfire import make_env
from repro.envs.wildfire.policies import POLICIES
from repro.runs.provenance import provenance
from repro.runs.results import write_result
from repro.studies.kit.options import Command, Folders, add_common
from repro.studies.transfer.study import TransferConfig, test_env_seed
from repro.studies.wildfire.study import adr, evaluate

POLICY_STREAM = 3
"""Child of the root seed that drives the heuristics' random draws (the transfer study uses
0-2)."""


def heuristic_adrs(cfg: TransferConfig, seed: int) -> pd.DataFrame:
    """One row per heuristic: its ADR and standard error on ``cfg``'s ED test episodes."""
    env = make_env(cfg.test_simulator())
    rows = []
    for i, (name, make) in enumerate(POLICIES.items()):
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(POLICY_STREAM, i)))
        mean, err = adr(evaluate(env, make(rng), cfg.test_episodes, test_env_seed(seed),
                                 keep_obs=False), env.gamma)
        rows.append(dict(semantics="corrected" if cfg.corrected else "released", policy=name,
                         episodes=cfg.test_episodes, adr=mean, sem=err))
    return pd.DataFrame(rows)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p, figures=False)
    add_config_arguments(p, TransferConfig, ("test_episodes",))


def configure(args: argparse.Namespace) -> Command[TransferConfig]:
    return Command.of(args, for_scale(TransferConfig, args.scale, **given_fields(
        args, TransferConfig, ("test_episodes",))))


def run(cmd: Command[TransferConfig], folders: Folders) -> int:
    cfg = cmd.study
    results = folders.open_results()
    t0 = time.perf_counter()
    table = pd.concat([heuristic_adrs(dataclasses.replace(cfg, corrected=corrected), cmd.seed)
                       for corrected in (False, True)], ignore_index=True)
    prov = provenance({"test_episodes": cfg.test_episodes}, command="wildfire-heuristics",
                      scale=folders.scale, seed=cmd.seed, wall_seconds=time.perf_counter() - t0)
    write_result(results / "wildfire_heuristics.csv", table, prov)
    print(table.to_string(index=False))
    return 0
