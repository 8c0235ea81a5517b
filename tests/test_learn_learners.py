"""The two named learners: the authors' settings as the default, each departure one switch, the
decision-counted batch as the released parallel sampler collects it, kept policies, and runs that
never resume as another learner's."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from repro.cli import main
from repro.envs import toy
from repro.learn import batch
from repro.learn.config import (LEARNERS, LEARNER_FIELDS, TrainConfig, learner_name,
                                study_train_config, train_config)
from repro.learn.policy import CategoricalPolicy
from repro.learn.trainer import Trainer
from repro.runs.run_folder import KEPT, load_checkpoint
from tests.conftest import tree_snapshot


def test_the_authors_learner_is_the_default_and_the_suite_one_switch():
    authors, suite = train_config("paper", "wildfire"), train_config("paper", "wildfire", "suite")
    assert (authors.hidden, authors.init, authors.normalize_obs, authors.fvp_subsample) == (
        (32,), "xavier", False, 1.0)
    assert (authors.batch_decisions, authors.batch_workers, authors.batch_episodes) == (
        12_000, 40, None)
    assert (suite.hidden, suite.init, suite.normalize_obs, suite.fvp_subsample) == (
        (32, 32), "orthogonal", True, 0.2)
    assert (suite.batch_decisions, suite.batch_episodes) == (None, 600)
    assert train_config("paper", "bus", "suite").batch_episodes == 540
    assert learner_name(authors) == "authors" and learner_name(suite) == "suite"
    assert LEARNERS["authors"] == TrainConfig()
    assert LEARNER_FIELDS == ("hidden", "init", "fvp_subsample", "normalize_obs")


def test_a_batch_size_in_the_other_unit_switches_the_unit():
    cfg = train_config("quick", "wildfire", "authors", batch_episodes=80)
    assert (cfg.batch_episodes, cfg.batch_decisions) == (80, None)
    assert learner_name(cfg) == "custom"
    cfg = train_config("quick", "wildfire", "suite", batch_decisions=5000)
    assert (cfg.batch_episodes, cfg.batch_decisions) == (None, 5000)
    cfg = study_train_config("quick", "wildfire", "authors", 3000, 150,
                             (("batch_episodes", 600),))
    assert (cfg.batch_episodes, cfg.batch_decisions) == (600, None)


def test_xavier_init_is_glorot_uniform_with_zero_biases():
    torch.manual_seed(0)
    net = CategoricalPolicy(28, 6, (32,), "xavier").net
    for layer in (m for m in net if isinstance(m, torch.nn.Linear)):
        fan_out, fan_in = layer.weight.shape
        bound = np.sqrt(6 / (fan_in + fan_out))
        w = layer.weight.detach().numpy()
        assert np.abs(w).max() <= bound and np.abs(w).max() > 0.9 * bound
        assert abs(w.var() - bound ** 2 / 3) < 0.25 * bound ** 2 / 3
        assert not layer.bias.detach().numpy().any()


def test_episodes_started_follows_the_parallel_sampler():
    # two workers; episodes of 5, 1, 1, 1, 7 decisions: worker 0 runs episode 0 (0-5), worker 1
    # runs 1 (0-1), 2 (1-2), 3 (2-3), 4 (3-10). Finished by time 3: 1, 2, 3 = 3 decisions; at 5
    # episode 0 ends: 8.
    d = np.array([5, 1, 1, 1, 7, 1, 1])
    assert batch.episodes_started(d, 3, 2) == 4   # reached at t = 3: episodes 0-3 started
    assert batch.episodes_started(d, 8, 2) == 5   # reached at t = 5 with episode 4 in flight
    assert batch.episodes_started(d, 100, 2) is None  # the stream ends first
    # whatever the target, every worker starts an episode
    assert batch.episodes_started(np.ones(50, int), 1, 40) == 40
    # one worker: episodes in order until the count is reached
    assert batch.episodes_started(np.array([3, 3, 3, 3]), 7, 1) == 3


def test_a_decision_counted_batch_is_a_deterministic_prefix_of_its_stream():
    env = toy.make_env(toy.ToyConfig())
    rng = lambda: np.random.default_rng(1)  # noqa: E731

    def policy_of(gen):
        return lambda b: gen.integers(0, toy.N_ACTIONS, len(b))

    seed = np.random.SeedSequence(4, spawn_key=(2, 0))
    a = batch.sample(env, policy_of(rng()), 500, 8, seed)
    b = batch.sample(env, policy_of(rng()), 500, 8, seed)
    assert np.array_equal(a.obs, b.obs) and np.array_equal(a.actions, b.actions)
    per_episode = np.bincount(a.path_episode, np.diff(a.path_start))
    assert len(per_episode) == batch.episodes_started(per_episode.astype(int), 500, 8)
    assert a.n_decisions >= 500 and len(a.episode_return) >= 8


def test_kept_policies_are_the_last_epochs_and_the_last_is_the_final_one(tmp_path):
    cfg = train_config("quick", "toy", batch_decisions=200, batch_workers=4, epochs=3)
    trainer = Trainer(cfg, toy.make_env(toy.ToyConfig()), tmp_path)
    trainer.train()
    kept = sorted(p.name for p in (tmp_path / KEPT).iterdir())
    assert kept == ["epoch0000.pt", "epoch0001.pt", "epoch0002.pt"]
    last, final = load_checkpoint(tmp_path / KEPT / kept[-1]), trainer.policy.state_dict()
    assert all(torch.equal(last["policy"][k], final[k]) for k in final)
    assert last["run_config"]["train"]["init"] == "xavier"


def test_a_run_never_resumes_as_another_learner(tmp_path, capsys):
    opts = ["train", "--env", "toy", "--epochs", "1", "--batch-decisions", "100",
            "--batch-workers", "2", "--out", str(tmp_path)]
    assert main([*opts, "--learner", "suite"]) == 0
    before = tree_snapshot(tmp_path)
    capsys.readouterr()
    assert main([*opts, "--epochs", "2"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out" in err
    assert tree_snapshot(tmp_path) == before
    saved = json.loads((tmp_path / "config.json").read_text())["train"]
    assert (saved["hidden"], saved["init"], saved["normalize_obs"]) == ([32, 32], "orthogonal",
                                                                        True)


@pytest.mark.parametrize("bad, param", [
    (["--learner", "rllab"], "--learner"),
    (["--init", "he"], "--init"),
    (["--batch-decisions", "0"], "--batch-decisions"),
    (["--batch-workers", "0"], "--batch-workers"),
    (["--batch-decisions", "100", "--batch-episodes", "5"], "--batch-decisions"),
])
def test_bad_learner_options_exit_2_with_one_line(tmp_path, capsys, bad, param):
    try:
        code = main(["train", "--env", "toy", "--out", str(tmp_path / "run"), *bad])
    except SystemExit as exit_:  # argparse's own refusal of a value outside the choices
        code = exit_.code
    assert code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and param in err
    assert not (tmp_path / "run").exists()


def test_a_study_setting_other_than_the_batch_size_keeps_the_studys_batch():
    cfg = study_train_config("quick", "wildfire", "authors", 3000, 150, (("batch_workers", 8),))
    assert (cfg.batch_decisions, cfg.batch_workers, cfg.batch_episodes) == (3000, 8, None)
