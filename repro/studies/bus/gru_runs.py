"""The GRU runs behind the bus pictures' ``gru`` and ``gru-greedy`` panels (claim C5): the
released ``experiment_2017_06_01_gae_2_with_featnet``, the policy the paper's arrival and load
figures were drawn from, trained as released (:mod:`repro.learn.gru`; lambda 2, 500 epochs of
12,000 decisions from 40 workers, the finite-difference Fisher products), ``seeds`` runs of it.

Each run is one checkpointed folder ``gru_lam2_dec<batch>_seed<s>`` under ``<runs-dir>/<the
corridor's semantics>/`` (beside the lambda sweep's; re-running skips what is finished). The
pictures take the run with the best test return: the mean return of ``test_episodes`` training
episodes (3 h) with sampled actions, each run's drawn from the stream of its name. Writes
results/bus_gru_runs.csv: one row per run (seed, run, final_return: its mean average return over
the last ``final_epochs`` epochs, test_return, best).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pandas as pd

from repro.core.config import Validated, for_scale
from repro.envs.bus import BusConfig, make_env
from repro.learn.config import train_config
from repro.runs.provenance import provenance
from repro.runs.results import write_result
from repro.studies.bus.policies import TrainedPolicy
from repro.studies.bus.sweeps import runs_folder
from repro.studies.kit.options import Folders, Workers
from repro.studies.kit.sweep import TrainJob, policy_stream, run_dir, run_sweep

RUNS_CSV = "bus_gru_runs.csv"
TEST_STREAM = 8
"""The child stream, of a run's name (root 0), that its test episodes' actions draw from."""


@dataclass(frozen=True)
class GruRunsConfig(Validated):
    """The GRU runs of the bus pictures, and how the best is chosen."""

    seeds: int = 5
    """Training runs (seeds 0, 1, ...)."""
    epochs: int = 500
    """Policy updates per run (the released runner.sh: 500)."""
    lam: float = 2.0
    """M-GAE lambda (the run's name: ``gae_2``)."""
    batch_decisions: int = 12000
    """Decisions per epoch (the released runner's default ``batch_size``)."""
    batch_workers: int = 40
    """Sampling workers (runner.sh's ``--n_parallel 40``)."""
    test_episodes: int = 30
    """Sampled episodes that score each run (the released ``test()`` simulates 30)."""
    final_epochs: int = 10
    """A run's final training return: its mean average return over these last epochs."""

    SCALES: ClassVar[dict[str, dict[str, Any]]] = {
        "smoke": dict(seeds=2, epochs=2, batch_decisions=300, batch_workers=4, test_episodes=2,
                      final_epochs=1),
        "quick": dict(seeds=3, epochs=30, test_episodes=10, final_epochs=5),
        "paper": {},
    }

    def validate(self) -> None:
        self.check(self.seeds >= 1, "seeds", "an integer >= 1")
        self.check(self.epochs >= 1, "epochs", "an integer >= 1")
        self.check(self.test_episodes >= 1, "test_episodes", "an integer >= 1")
        self.check(1 <= self.final_epochs <= self.epochs, "final_epochs", "in [1, epochs]")


def jobs(cfg: GruRunsConfig, bus: BusConfig) -> list[TrainJob]:
    return [TrainJob(f"gru_lam{cfg.lam:g}_dec{cfg.batch_decisions}_seed{s}",
                     train_config("quick", "bus", policy="gru", seed=s, epochs=cfg.epochs,
                                  lam=cfg.lam, batch_decisions=cfg.batch_decisions,
                                  batch_workers=cfg.batch_workers), bus)
            for s in range(cfg.seeds)]


def test_return(run: Path, bus: BusConfig, episodes: int) -> float:
    """Mean return of ``episodes`` training episodes of ``run``'s policy, sampled."""
    rng = np.random.default_rng(policy_stream(0, TEST_STREAM, run.name))
    policy = TrainedPolicy(run, bus, "--runs-dir", rng)
    return float(make_env(bus).rollout(policy, episodes).episode_return.mean())


def best_gru_run(folders: Folders, bus: BusConfig, workers: Workers) -> Path:
    """Train (or resume, or find finished) the GRU runs of the folders' scale in their runs
    folder on ``workers``, score each, write
    bus_gru_runs.csv into their results folder, and return the best run's folder."""
    cfg = for_scale(GruRunsConfig, folders.scale)
    root = folders.run_root(runs_folder(bus))
    t0 = time.perf_counter()
    job_list = jobs(cfg, bus)
    runs = run_sweep(job_list, root, workers)
    rows = []
    for job, folder in zip(job_list, runs):
        prog = pd.read_csv(folder / "progress.csv").iloc[:cfg.epochs]
        rows.append(dict(seed=job.train.seed, run=str(run_dir(root, job)),
                         final_return=float(prog.average_return.iloc[-cfg.final_epochs:].mean()),
                         test_return=test_return(folder, bus, cfg.test_episodes)))
    table = pd.DataFrame(rows)
    table["best"] = np.arange(len(table)) == int(np.argmax(table.test_return.to_numpy()))
    prov = provenance(cfg, command="bus-gru-runs", scale=folders.scale, seed=0,
                      wall_seconds=time.perf_counter() - t0, extra={"runs_dir": str(root)})
    write_result(folders.results / RUNS_CSV, table, prov)
    return Path(table.run[table.best].iloc[0])
