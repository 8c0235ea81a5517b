"""A sweep's workers take its runs longest first (repro.studies.kit.sweep.longest_first)."""

from __future__ import annotations

import dataclasses
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


def test_a_recurrent_policys_runs_go_before_an_mlps_of_the_same_size():
    """A GRU's run of the bus costs about 60 times an MLP's of the same epochs and batch, though
    its batch takes as many bytes: the pictures' GRU runs, the longest of every study's, first."""
    cfg = sweep_config("paper", "authors")
    mlp = [(j, Path("runs")) for j in jobs(cfg, "lambda", 0, BusConfig())][:2]
    gru = [(dataclasses.replace(j, name=j.name + "-gru",
                                train=dataclasses.replace(j.train, policy="gru")), root)
           for j, root in mlp]
    assert longest_first(mlp + gru) == gru + mlp
