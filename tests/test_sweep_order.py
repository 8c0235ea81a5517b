"""A sweep's workers take its runs longest first (repro.studies.kit.sweep.longest_first)."""

from __future__ import annotations

from pathlib import Path

from repro.envs.bus import BusConfig
from repro.studies.bus.sweeps import jobs, sweep_config
from repro.studies.kit.sweep import longest_first


def test_the_largest_batches_train_first_and_ties_keep_their_order():
    cfg = sweep_config("paper", "authors")
    batch_jobs = jobs(cfg, "batch", 0, BusConfig())
    ordered = [job for job, _ in longest_first([(j, Path("runs")) for j in batch_jobs])]
    assert sorted(j.name for j in ordered) == sorted(j.name for j in batch_jobs)
    assert [j.train.batch_decisions for j in ordered] == [12000] * 5 + [1200] * 5 + [120] * 5
    assert [j.train.seed for j in ordered[:5]] == [0, 1, 2, 3, 4]
    lam = jobs(cfg, "lambda", 0, BusConfig())  # one size: the order given
    runs = [(j, Path("runs", j.name)) for j in lam]
    assert longest_first(runs) == runs
