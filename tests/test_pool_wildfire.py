"""The released pool on an environment that draws random numbers itself (the wildfire): an episode
is a function of its start in the pool stream (its draws first, then its actions' uniforms), the
workers move on by both, identical workers give copies, both engines run the same episodes, and
the runs are deterministic (tests/test_pool.py: the bus, and the refusal of an environment that
draws and cannot run given draws)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from repro.cli import main
from repro.core.rollout import DecisionBatch, RunsOnDraws
from repro.envs.wildfire import WildfireConfig, make_env, make_reference_env
from repro.envs.wildfire.params import draws_from_uniforms, stream_draws
from repro.learn.pool import ReleasedPool, runs_on_pool, stream_uniforms
from repro.runs.run_folder import TIMING_COLUMNS

SEED = np.random.SeedSequence(7)
CFG = WildfireConfig(hold_table_size=8, gamma=0.05)  # a short table: 51 holds for T_max 106 s


class Recording:
    """An acting function that picks action floor(u n_actions) and keeps each episode's
    uniforms in the order it is given them."""

    def __init__(self, n_actions: int):
        self.n_actions = n_actions
        self.seen: dict[int, list[float]] = {}

    def __call__(self, batch: DecisionBatch, u: np.ndarray) -> np.ndarray:
        for e, x in zip(batch.episode, u):
            self.seen.setdefault(int(e), []).append(float(x))
        return (u * self.n_actions).astype(np.int64)


def episode(ro, e):
    """The decisions of episode ``e`` of a rollout: (actions, obs, rewards, durations)."""
    paths = np.flatnonzero(ro.path_episode == e)
    rows = np.arange(ro.path_start[paths[0]], ro.path_start[paths[-1] + 1])
    return ro.actions[rows], ro.obs[rows], ro.rewards[rows], ro.durations[rows]


def test_the_engines_take_draws_from_a_stream():
    for env in (make_env(CFG), make_reference_env(CFG)):
        assert isinstance(env, RunsOnDraws) and runs_on_pool(env)
        assert env.draws_per_episode == CFG.n_agents * (2 + CFG.hold_table)


def test_draws_from_uniforms_are_starts_then_normal_holds():
    u = np.random.default_rng(0).random((400, stream_draws(CFG)))
    u[0, :] = 0.0  # the generator's lowest value stays finite
    draws = draws_from_uniforms(CFG, u)
    np.testing.assert_array_equal(draws.starts[1:], -1 + 2 * u[1:, :6].reshape(-1, 3, 2))
    assert np.isfinite(draws.holds).all() and draws.holds.shape == (400, 3, CFG.hold_table)
    holds = draws.holds[1:].ravel()
    assert abs(holds.mean() - CFG.hold_mean) < 0.01 and abs(holds.std() - CFG.hold_std) < 0.01
    with pytest.raises(ValueError, match="shape"):
        draws_from_uniforms(CFG, u[:, 1:])


def test_an_episode_is_a_function_of_its_start():
    env = make_env(CFG)
    pool = ReleasedPool(SEED, 1)
    alone = pool.simulate(env, Recording(env.n_actions), [1000])
    mixed = pool.simulate(env, Recording(env.n_actions), [5, 1000, 20000])
    for a, b in zip(episode(alone, 0), episode(mixed, 1)):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(episode(mixed, 0)[1], episode(mixed, 1)[1])


def test_the_draws_come_first_then_one_uniform_per_decision():
    env = make_env(CFG)
    k = env.draws_per_episode
    act = Recording(env.n_actions)
    ro = ReleasedPool(SEED, 1).simulate(env, act, [300])
    stream = stream_uniforms(SEED, [300], k + ro.n_decisions)[0]
    starts = ro.obs[ro.path_start[:-1], :2]  # each UAV's first observation: where it starts
    np.testing.assert_array_equal(starts, -1 + 2 * stream[:6].reshape(3, 2))
    np.testing.assert_array_equal(act.seen[0], stream[k:])


def test_workers_move_on_by_the_draws_and_the_decisions():
    env = make_env(CFG)
    pool = ReleasedPool(SEED, 3)
    pool.offsets[:] = [0, 0, 50]
    ro, distinct = pool.sample(env, Recording(env.n_actions), target=1)
    assert distinct == 2 and len(ro.episode_return) == 3
    first = np.diff(ro.path_start)[ro.path_episode == 0].sum()
    third = np.diff(ro.path_start)[ro.path_episode == 2].sum()
    k = env.draws_per_episode
    np.testing.assert_array_equal(pool.offsets, [k + first, k + first, 50 + k + third])


def test_both_engines_run_the_same_pool_episodes():
    pool = ReleasedPool(SEED, 1)
    fast, ref = (pool.simulate(env, Recording(env.n_actions), [0, 4321])
                 for env in (make_env(CFG), make_reference_env(CFG)))
    np.testing.assert_array_equal(fast.actions, ref.actions)
    np.testing.assert_array_equal(fast.path_start, ref.path_start)
    np.testing.assert_allclose(fast.obs, ref.obs, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.rewards, ref.rewards, rtol=0, atol=1e-9)


def train(tmp_path, name, *extra):
    out = tmp_path / name
    assert main(["train", "--env", "wildfire", "--scale", "smoke", "--sampler", "released-pool",
                 "--out", str(out), *extra]) == 0
    return pd.read_csv(out / "progress.csv").drop(columns=TIMING_COLUMNS)


def test_identical_workers_give_copies_and_runs_repeat(tmp_path):
    tiny = ["--batch-decisions", "1", "--batch-workers", "3", "--epochs", "2"]
    a, b = train(tmp_path, "a", *tiny), train(tmp_path, "b", *tiny)
    assert a.to_csv(index=False) == b.to_csv(index=False)
    assert a.distinct_episodes.iloc[0] == 1 and (a.batch_episodes == 3).all()
    assert a.decisions.iloc[0] % 3 == 0
    c = train(tmp_path, "c", "--epochs", "2", "--seed", "1")
    assert not c.equals(train(tmp_path, "d", "--epochs", "2"))



def test_a_resumed_run_equals_an_uninterrupted_one(tmp_path):
    whole = train(tmp_path, "whole", "--epochs", "3")
    train(tmp_path, "resumed", "--epochs", "1")
    assert train(tmp_path, "resumed", "--epochs", "3").to_csv(index=False) == whole.to_csv(
        index=False)


def test_the_transfer_study_on_the_pool_writes_files_of_its_own(tmp_path, monkeypatch):
    monkeypatch.setenv("REPRO_QUIET", "1")
    dirs = {d: tmp_path / d for d in ("results", "figures", "runs")}
    assert main(["transfer", "--sampler", "released-pool", "--sim-version", "2017-04-22",
                 "--scale", "smoke", "--simulator", "ED", "--simulator", "FS-1",
                 "--test-episodes", "5", "--n-jobs", "1",
                 *(x for d, p in dirs.items() for x in (f"--{d}-dir", str(p)))]) == 0
    stem = "transfer_20170422_pool"
    assert sorted(p.name for p in dirs["results"].glob("*.csv")) == [f"{stem}.csv",
                                                                      f"{stem}_summary.csv"]
    assert (dirs["figures"] / f"{stem}.png").exists()
    runs = dirs["runs"] / "transfer-20170422-pool" / "smoke"
    assert sorted(p.name for p in runs.iterdir()) == ["ed-th3-seed0", "fs1-th3-seed0"]
    config = json.loads((runs / "ed-th3-seed0" / "config.json").read_text())
    assert config["train"]["sampler"] == "released-pool" and config["env"]["r_pen"] == -1.0
    progress = pd.read_csv(runs / "ed-th3-seed0" / "progress.csv")
    assert (progress.distinct_episodes < progress.batch_episodes).all()  # copies


@pytest.mark.parametrize("bad", [["--sampler", "pooled"],
                                 ["--sampler", "released-pool", "--learner", "suite"]])
def test_a_bad_sampler_of_the_transfer_study_exits_2(tmp_path, monkeypatch, capsys, bad):
    monkeypatch.chdir(tmp_path)
    try:
        code = main(["transfer", "--scale", "smoke", *bad])
    except SystemExit as exit_:  # argparse's errors
        code = exit_.code
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--sampler" in err
    assert list(tmp_path.iterdir()) == []
