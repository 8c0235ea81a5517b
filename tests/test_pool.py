"""The released pool as a sampler setting: its counter and worker order, the lockstep of the bus at
a batch of 120, more distinct episodes at larger batches, copies in the batch, determinism and
resume, and its refusals."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import torch

from repro.cli import main
from repro.envs import bus
from repro.learn.config import train_config
from repro.learn.policy import Sampler
from repro.learn.pool import ReleasedPool, collect
from repro.runs.run_folder import CHECKPOINT, load_checkpoint
from repro.learn.trainer import Trainer
from repro.runs.run_folder import TIMING_COLUMNS


def test_identical_workers_move_in_lockstep_below_one_episode():
    runs, pos = collect(np.zeros(40, np.int64), {0: 240}, target=120)
    assert runs == [(w, 0) for w in range(40)]
    np.testing.assert_array_equal(pos, np.full(40, 240))


def test_workers_finishing_short_of_the_count_start_another():
    offsets = np.zeros(40, np.int64)
    assert collect(offsets, {0: 240}, target=1200) == {240}  # the next episode is asked for
    runs, pos = collect(offsets, {0: 240, 240: 240}, target=1200)
    # 40 identical finishes; the first four leave the counter short (240 ... 960) and go on
    assert len(runs) == 44 and [w for w, s in runs if s == 240] == [0, 1, 2, 3]
    np.testing.assert_array_equal(pos, [480] * 4 + [240] * 36)
    assert [w for w, _ in runs] == sorted(w for w, _ in runs)  # by worker, as the batch holds


def test_shorter_episodes_finish_first():
    lengths = {0: 300, 100: 200, 300: 300}
    runs, pos = collect(np.array([0, 0, 100]), lengths, target=250)
    # worker 2's episode (200) ends first with the counter short, so it alone runs a second
    assert runs == [(0, 0), (1, 0), (2, 100), (2, 300)]
    np.testing.assert_array_equal(pos, [300, 300, 600])


def bus_trainer(batch: int, epochs: int, seed: int = 0, workers: int = 40) -> Trainer:
    cfg = train_config("quick", "bus", epochs=epochs, seed=seed, batch_decisions=batch,
                       batch_workers=workers, sampler="released-pool")
    return Trainer(cfg, bus.make_env(bus.BusConfig()), env_config=bus.BusConfig())


def test_bus_at_a_batch_of_120_learns_from_one_episode_per_epoch():
    frame = bus_trainer(120, epochs=4).train()
    assert (frame.distinct_episodes == 1).all() and (frame.batch_episodes == 40).all()
    assert (frame.decisions % 40 == 0).all() and (frame.decisions > 40 * 120).all()


def test_the_batch_holds_every_worker_copy():
    trainer = bus_trainer(120, epochs=1)
    pool = ReleasedPool(np.random.SeedSequence(1), 5)
    act = Sampler(trainer.policy, trainer.normalizer, trainer.rng).act
    ro, distinct = pool.sample(trainer.env, act, 120)
    assert distinct == 1 and len(ro.episode_return) == 5
    per = ro.n_decisions // 5
    assert ro.path_start[trainer.env.n_agents] == per  # the first episode's paths
    for e in range(1, 5):
        for field in ("obs", "actions", "rewards", "durations"):
            a = getattr(ro, field)
            np.testing.assert_array_equal(a[:per], a[e * per:(e + 1) * per])
    np.testing.assert_array_equal(pool.offsets, np.full(5, per))
    # the next epoch's episode draws the stream on from there: another episode
    ro2, _ = pool.sample(trainer.env, act, 120)
    assert not np.array_equal(ro2.actions[:per], ro.actions[:per])


def test_larger_batches_hold_more_distinct_episodes():
    means = [bus_trainer(b, epochs=5).train().distinct_episodes.mean()
             for b in (120, 1200, 12000)]
    assert means[0] == 1 < means[1] < means[2]


def test_same_seed_same_bytes_and_resume_equals_uninterrupted(tmp_path):
    opts = ["train", "--env", "bus", "--batch-decisions", "1200", "--sampler", "released-pool"]
    for name, seed in (("a", "3"), ("b", "3"), ("c", "4")):
        assert main([*opts, "--seed", seed, "--epochs", "4", "--out", str(tmp_path / name)]) == 0
    assert main([*opts, "--seed", "3", "--epochs", "2", "--out", str(tmp_path / "r")]) == 0
    assert main([*opts, "--seed", "3", "--epochs", "4", "--out", str(tmp_path / "r")]) == 0
    table = {n: pd.read_csv(tmp_path / n / "progress.csv").drop(columns=TIMING_COLUMNS)
             for n in "abcr"}
    for other in "br":
        assert (table[other].to_csv(index=False) == table["a"].to_csv(index=False)), other
    assert not table["c"].equals(table["a"])
    assert table["a"].distinct_episodes.max() > 1
    ck = {n: load_checkpoint(tmp_path / n / CHECKPOINT) for n in "ar"}
    assert torch.equal(ck["a"]["pool_offsets"], ck["r"]["pool_offsets"])
    config = json.loads((tmp_path / "a" / "config.json").read_text())
    assert config["train"]["sampler"] == "released-pool"


def test_a_run_never_resumes_as_another_sampler(tmp_path, capsys):
    out = str(tmp_path / "run")
    opts = ["train", "--env", "bus", "--scale", "smoke", "--epochs", "1", "--out", out]
    assert main([*opts, "--sampler", "released-pool"]) == 0
    assert main(opts) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "sampler" in err


@pytest.mark.parametrize("env, bad, param", [
    ("bus", ["--sampler", "pool"], "--sampler"),
    ("bus", ["--sampler", "released-pool", "--batch-episodes", "4"], "--sampler"),
    ("toy", ["--sampler", "released-pool"], "--sampler"),  # it draws and cannot take draws
])
def test_bad_sampler_exits_2_with_one_line(tmp_path, capsys, env, bad, param):
    out = tmp_path / "run"
    assert main(["train", "--env", env, "--scale", "smoke", "--out", str(out), *bad]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and param in err
    assert not out.exists()


def test_damaged_worker_positions_are_refused(tmp_path, capsys):
    out = tmp_path / "run"
    opts = ["train", "--env", "bus", "--scale", "smoke", "--sampler", "released-pool",
            "--out", str(out)]
    assert main([*opts, "--epochs", "1"]) == 0
    state = torch.load(out / CHECKPOINT, weights_only=True)
    state["pool_offsets"] = torch.tensor([-1, 0, 0, 0])
    torch.save(state, out / CHECKPOINT)
    assert main([*opts, "--epochs", "2"]) == 2
    assert "worker positions" in capsys.readouterr().err
