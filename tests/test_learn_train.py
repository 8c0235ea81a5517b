"""The trainer end to end: reaches the toy optimum, is deterministic, resumes exactly, rejects bad
options, and the real entry points run."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

from repro.cli import main
from repro.envs import toy
from repro.learn.config import train_config
from repro.learn.policy import Sampler
from repro.learn.trained_policy import policy_from_checkpoint
from repro.learn.trainer import Trainer
from repro.runs.run_folder import PROGRESS_COLUMNS, TIMING_COLUMNS
from repro.runs.results import read_provenance
from repro.runs.run_folder import CHECKPOINT, load_checkpoint
from tests.conftest import tree_snapshot

ROOT = Path(__file__).resolve().parents[1]


def toy_policy_table(trainer: Trainer) -> np.ndarray:
    """pi(a | c) of the trained policy for both contexts."""
    with torch.no_grad():
        z = trainer.normalizer(np.eye(toy.N_CONTEXTS))
        return trainer.policy(torch.as_tensor(z, dtype=torch.float32)).exp().double().numpy()


def test_reaches_toy_optimum():
    env_cfg = toy.ToyConfig()
    best_actions, best_adr = toy.optimal_policy(env_cfg)
    uniform_adr = toy.expected_adr(env_cfg, np.full((toy.N_CONTEXTS, toy.N_ACTIONS), 1 / 3))
    trainer = Trainer(train_config("quick", "toy", epochs=30, seed=1), toy.make_env(env_cfg))
    frame = trainer.train()
    probs = toy_policy_table(trainer)
    np.testing.assert_array_equal(probs.argmax(axis=1), best_actions)
    learned_adr = toy.expected_adr(env_cfg, probs)
    # within 1% of the optimum, having started about 40% below it
    assert (learned_adr >= best_adr - 0.01 * (best_adr - 0)
            and best_adr - uniform_adr > 0.3 * best_adr)
    # training curves: the batch estimate rose with the policy
    assert (frame.average_discounted_return.iloc[-5:].mean()
            > frame.average_discounted_return.iloc[0])
    assert (frame.kl <= 0.01).all()


def test_toy_exact_value_matches_simulation():
    cfg = toy.ToyConfig(n_agents=3, horizon=12)
    probs = np.array([[0.2, 0.5, 0.3], [0.6, 0.1, 0.3]])
    rng = np.random.default_rng(0)

    def policy(batch):
        p = probs[batch.obs.argmax(axis=1)]
        return (p.cumsum(axis=1) <= rng.random(len(p))[:, None]).sum(axis=1)

    ro = toy.make_env(cfg).rollout(policy, 4000, 3)
    est = ro.discounted_path_returns(cfg.gamma)
    se = est.reshape(4000, 3).mean(axis=1).std() / np.sqrt(4000)
    assert abs(est.mean() - toy.expected_adr(cfg, probs)) < 4 * se
    assert np.all(ro.durations > 0) and ro.path_start[-1] == ro.n_decisions


def tensors_equal(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "repro", *args], cwd=ROOT, capture_output=True,
                          text=True, env={"REPRO_QUIET": "1", "PATH": "/usr/bin:/bin"})


def test_resume_equals_uninterrupted_run(tmp_path):
    opts = ["train", "--env", "toy", "--batch-episodes", "6", "--seed", "3", "--horizon", "10"]
    # interrupted: 2 epochs, then the same command asking for 3 resumes from the checkpoint
    assert main([*opts, "--epochs", "2", "--out", str(tmp_path / "b")]) == 0
    assert len(pd.read_csv(tmp_path / "b" / "progress.csv")) == 2
    assert main([*opts, "--epochs", "3", "--out", str(tmp_path / "b")]) == 0
    # uninterrupted, twice, in this process
    for name in ("a", "c"):
        args = argparse.Namespace(n_agents=2, horizon=10, gamma=toy.ToyConfig.gamma)
        Trainer(train_config("quick", "toy", epochs=3, batch_episodes=6, seed=3),
                toy.make_env(toy.config_from_args(args)), tmp_path / name,
                toy.config_from_args(args)).train()
    ck = {n: load_checkpoint(tmp_path / n / CHECKPOINT) for n in "abc"}
    for other in "bc":
        assert ck[other]["epoch"] == 3
        for part in ("policy", "baseline"):
            assert tensors_equal(ck["a"][part], ck[other][part]), (other, part)
        for key in ("mean", "var"):
            np.testing.assert_array_equal(ck["a"]["normalizer"][key], ck[other]["normalizer"][key])
        assert ck["a"]["sampler_rng"] == ck[other]["sampler_rng"]
        frames = [pd.read_csv(tmp_path / n / "progress.csv").drop(columns=TIMING_COLUMNS)
                  for n in ("a", other)]
        pd.testing.assert_frame_equal(*frames, check_exact=True)
    assert ((tmp_path / "b" / "config.json").read_text()
            == (tmp_path / "a" / "config.json").read_text())
    # and a run with a different seed differs
    assert not tensors_equal(ck["a"]["policy"], Trainer(
        train_config("quick", "toy", epochs=1, seed=4), toy.make_env(toy.ToyConfig())
    ).policy.state_dict())


@pytest.mark.parametrize("stop", ["after_the_row", "in_the_row"])
def test_resume_after_a_stop_between_row_and_checkpoint(tmp_path, stop):
    """A run stopped after appending epoch e's row (whole or cut short) but before checkpointing
    epoch e resumes with the rows of its checkpoint."""
    opts = ["train", "--env", "toy", "--batch-episodes", "6", "--seed", "3", "--horizon", "10"]
    assert main([*opts, "--epochs", "3", "--out", str(tmp_path / "whole")]) == 0
    run = tmp_path / "stopped"
    assert main([*opts, "--epochs", "2", "--out", str(run)]) == 0
    progress = run / "progress.csv"
    third_row = (tmp_path / "whole" / "progress.csv").read_text().splitlines(keepends=True)[3]
    progress.write_text(progress.read_text() + (third_row if stop == "after_the_row"
                                                else third_row[:9]))
    assert main([*opts, "--epochs", "3", "--out", str(run)]) == 0
    a, b = (pd.read_csv(d / "progress.csv").drop(columns=TIMING_COLUMNS)
            for d in (tmp_path / "whole", run))
    pd.testing.assert_frame_equal(a, b, check_exact=True)


@pytest.mark.parametrize("damage", ["deleted", "short"])
def test_resume_refuses_a_progress_table_missing_checkpointed_rows(tmp_path, capsys, damage):
    """Rows of checkpointed epochs cannot be rebuilt: resuming says so (exit 2), touching
    nothing."""
    opts = ["train", "--env", "toy", "--batch-episodes", "6", "--horizon", "10", "--out",
            str(tmp_path)]
    assert main([*opts, "--epochs", "2"]) == 0
    progress = tmp_path / "progress.csv"
    if damage == "deleted":
        progress.unlink()
    else:
        progress.write_text("".join(progress.read_text().splitlines(keepends=True)[:2]))
    before = tree_snapshot(tmp_path)
    capsys.readouterr()
    assert main([*opts, "--epochs", "3"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out" in err and "holds the 2 epochs" in err
    assert tree_snapshot(tmp_path) == before


def test_cli_smoke_and_checkpoint_policy(tmp_path):
    out = tmp_path / "run"
    res = run_cli("train", "--env", "toy", "--scale", "smoke", "--hidden", "8", "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert {"config.json", "progress.csv", CHECKPOINT} <= {p.name for p in out.iterdir()}
    frame = pd.read_csv(out / "progress.csv")
    # smoke: 300 decisions of whole episodes from 4 workers per epoch
    assert list(frame.epoch) == [0, 1] and (frame.decisions >= 300).all()
    assert (frame.batch_episodes >= 4).all()
    prov = json.loads((out / "progress.provenance.json").read_text())
    assert prov["command"] == "train" and prov["git_commit"] and "torch" in prov["versions"]
    assert prov["config"]["train"]["hidden"] == [8] and prov["epochs_after"] == 2
    sampler = policy_from_checkpoint(out / CHECKPOINT, np.random.default_rng(0))
    ro = toy.make_env(toy.ToyConfig()).rollout(sampler, 3, 0)
    assert ro.n_decisions > 0 and set(np.unique(ro.actions)) <= {0, 1, 2}


@pytest.mark.parametrize("bad, param", [
    (["--lam", "-0.5"], "--lam"),
    (["--max-kl", "0"], "--max-kl"),
    (["--batch-episodes", "0"], "--batch-episodes"),
    (["--epochs", "0"], "--epochs"),
    (["--gamma", "0"], "--gamma"),
    (["--hidden", "0"], "--hidden"),
    (["--fvp-subsample", "0"], "--fvp-subsample"),
    (["--fvp-subsample", "1.5"], "--fvp-subsample"),
    (["--scale", "huge"], "--scale"),
    (["--gamma", "inf"], "--gamma"),
    (["--lam", "inf"], "--lam"),
    (["--max-kl", "inf"], "--max-kl"),
    (["--seed", "-1"], "--seed"),
    (["--advantage", "gae"], "--advantage"),
])
def test_bad_options_exit_2_with_one_line(tmp_path, capsys, bad, param):
    out = tmp_path / "run"
    assert main(["train", "--env", "toy", "--out", str(out), *bad]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and param in err
    assert not out.exists()


@pytest.mark.parametrize("env", ["wildfire", "bus"])
@pytest.mark.parametrize("gamma", ["0", "-1", "inf"])
def test_bad_gamma_of_each_environment_exits_2(tmp_path, capsys, env, gamma):
    out = tmp_path / "run"
    assert main(["train", "--env", env, "--out", str(out), "--gamma", gamma]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--gamma" in err
    assert not out.exists()


@pytest.mark.parametrize("env, gamma", [("wildfire", 0.05), ("bus", 2e-5)])
def test_gamma_option_reaches_the_environment(tmp_path, env, gamma):
    out = tmp_path / "run"
    assert main(["train", "--env", env, "--scale", "smoke", "--epochs", "1", "--batch-episodes",
                 "2", "--out", str(out), "--gamma", str(gamma)]) == 0
    assert json.loads((out / "config.json").read_text())["env"]["gamma"] == gamma


def test_unknown_env_exits_2(tmp_path, capsys):
    assert main(["train", "--env", "chess", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--env" in err


def test_resume_with_other_settings_refused(tmp_path, capsys):
    out = str(tmp_path / "run")
    assert main(["train", "--env", "toy", "--scale", "smoke", "--out", out]) == 0
    assert main(["train", "--env", "toy", "--scale", "smoke", "--lam", "0.5", "--out", out]) == 2
    assert "--out" in capsys.readouterr().err


def test_out_folder_of_other_files_refused(tmp_path, capsys):
    out = tmp_path / "figures"
    out.mkdir()
    (out / "plot.png").write_bytes(b"png")
    assert main(["train", "--env", "toy", "--scale", "smoke", "--out", str(out)]) == 2
    assert "--out" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["plot.png"]
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["train", "--env", "toy", "--scale", "smoke", "--out", str(empty)]) == 0


def test_resume_of_a_run_older_than_a_setting(tmp_path):
    """A run folder written before a setting existed resumes when the setting is at the value the
    run had (``BEFORE_ADDED``: no decision limit; the default fvp_subsample), and not otherwise."""
    out = tmp_path / "run"
    opts = ["train", "--env", "wildfire", "--scale", "smoke", "--out", str(out)]
    assert main([*opts, "--epochs", "1", "--max-decisions", "0"]) == 0
    config = json.loads((out / "config.json").read_text())
    del config["env"]["max_decisions"], config["train"]["fvp_subsample"]
    (out / "config.json").write_text(json.dumps(config))
    old = pd.read_csv(out / "progress.csv").drop(columns="truncated_episodes")  # before it existed
    old.to_csv(out / "progress.csv", index=False)
    assert main([*opts, "--epochs", "2"]) == 2  # the default limit, 1000
    assert main([*opts, "--epochs", "2", "--max-decisions", "50"]) == 2
    assert main([*opts, "--epochs", "2", "--max-decisions", "0"]) == 0
    progress = pd.read_csv(out / "progress.csv")
    assert list(progress.columns) == PROGRESS_COLUMNS and len(progress) == 2
    assert progress.truncated_episodes.isna().tolist() == [True, False]  # unknown, then 0


def test_the_advantage_estimator_is_part_of_a_run(tmp_path, capsys):
    """config.json records the estimator; a run recorded before the setting existed is an M-GAE run
    and resumes as one, and no folder resumes under another estimator."""
    out = tmp_path / "run"
    opts = ["train", "--env", "toy", "--scale", "smoke", "--out", str(out)]
    assert main([*opts, "--epochs", "1"]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["train"]["advantage"] == "m-gae"
    del config["train"]["advantage"]
    (out / "config.json").write_text(json.dumps(config))
    assert main([*opts, "--epochs", "2", "--advantage", "decision-gae"]) == 2
    assert "advantage" in capsys.readouterr().err
    assert main([*opts, "--epochs", "2"]) == 0
    other = tmp_path / "other"
    assert main(["train", "--env", "toy", "--scale", "smoke", "--out", str(other),
                 "--advantage", "duration-gae"]) == 0
    assert json.loads((other / "config.json").read_text())["train"]["advantage"] == "duration-gae"


def test_episodes_cut_at_the_decision_limit_are_reported(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["train", "--env", "wildfire", "--scale", "smoke", "--out", str(out),
                 "--max-decisions", "2"]) == 0
    progress = pd.read_csv(out / "progress.csv")
    assert (progress.truncated_episodes == progress.batch_episodes).all()
    assert f"note: {progress.batch_episodes.sum()} of {progress.batch_episodes.sum()} training " \
        "episodes ended at the decision limit" in capsys.readouterr().out


def test_bench_learn_smoke(tmp_path):
    assert main(["bench-learn", "--scale", "smoke", "--results-dir", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "bench_learn.csv")
    assert list(table.columns[:4]) == ["env", "epoch", "batch_episodes", "decisions"]
    assert (table.seconds_sim > 0).all() and (table.seconds_update > 0).all()
    assert (tmp_path / "bench_learn.provenance.json").exists()
    pieces = pd.read_csv(tmp_path / "bench_learn_pieces.csv")
    assert pieces.part.tolist() == ["simulation"] + ["update"] * 5 + ["trpo"] * 5
    assert "normaliser update" not in pieces.piece.tolist()  # the authors' learner has none
    assert (pieces.seconds > 0).all() and pieces.vs_simulation[0] == 1
    assert np.allclose(pieces.seconds_per_epoch, pieces.calls * pieces.seconds)
    assert pieces.calls[pieces.piece == "line-search trial"].item() >= 1
    assert (tmp_path / "bench_learn_pieces.provenance.json").exists()


def test_bench_learn_names_the_suite_learners_tables_apart(tmp_path):
    assert main(["bench-learn", "--scale", "smoke", "--learner", "suite",
                 "--results-dir", str(tmp_path)]) == 0
    assert sorted(p.name for p in tmp_path.glob("*.csv")) == [
        "bench_learn_suite.csv", "bench_learn_suite_pieces.csv"]
    recorded = read_provenance(tmp_path / "bench_learn_suite.csv")["config"]["train"]
    assert recorded["hidden"] == [32, 32]
    pieces = pd.read_csv(tmp_path / "bench_learn_suite_pieces.csv")
    assert "normaliser update" in pieces.piece.tolist()


@pytest.mark.slow
def test_wildfire_trained_policy_beats_random():
    wildfire = pytest.importorskip("repro.envs.wildfire")
    parser = argparse.ArgumentParser()
    wildfire.add_env_arguments(parser)
    env_cfg = wildfire.config_from_args(parser.parse_args([]))
    env = wildfire.make_env(env_cfg)
    trainer = Trainer(train_config("quick", "wildfire", epochs=10, batch_episodes=60, seed=0), env)
    trainer.train()
    rng = np.random.default_rng(1)
    trained = env.rollout(Sampler(trainer.policy, trainer.normalizer, rng), 300, 12345)
    random = env.rollout(lambda b: rng.integers(0, env.n_actions, len(b)), 300, 12345)
    assert (trained.discounted_path_returns(env.gamma).mean()
            > random.discounted_path_returns(env.gamma).mean())

