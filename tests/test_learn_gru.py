"""The recurrent policy (``--policy gru``): its sampler threads each agent's state as training
does, its two Fisher-vector products agree, a run resumes exactly, bad options are refused in one
line, and the real entry points run it."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import torch

from repro.cli import main
from repro.core.rollout import DecisionBatch
from repro.envs import env_package, toy
from repro.learn import gru
from repro.learn.config import train_config
from repro.learn.policy import ObsNormalizer
from repro.learn.trained_policy import policy_from_checkpoint
from repro.learn.trainer import Trainer
from repro.runs.run_folder import TIMING_COLUMNS
from repro.runs.run_folder import CHECKPOINT, load_checkpoint
from tests.conftest import tree_snapshot
from tests.test_learn_train import run_cli, tensors_equal

FVP_TOLERANCE = 1e-5
"""Relative difference allowed between the finite-difference and the exact Fisher products (in
float64 they differ by about 1e-6 on a bus batch: the difference's rounding over its 2 eps)."""


def bus_batch(policy: gru.GRUPolicy, episodes: int = 2):
    pkg = env_package("bus")
    env = pkg.make_env(pkg.BusConfig())
    sampler = gru.GRUSampler(policy, ObsNormalizer(env.obs_dim), np.random.default_rng(0))
    ro = env.rollout(sampler, episodes)
    return ro, gru.Paths.pack(ro.obs, ro.actions, ro.path_start, env.n_actions)


def test_the_sampler_runs_each_agents_state_over_its_own_decisions():
    torch.manual_seed(0)
    pkg = env_package("bus")
    env = pkg.make_env(pkg.BusConfig())
    policy = gru.GRUPolicy(env.obs_dim, env.n_actions)
    normalizer = ObsNormalizer(env.obs_dim)
    sampler = gru.GRUSampler(policy, normalizer, np.random.default_rng(1))
    seen = {}  # (episode, agent) -> per decision the sampler's log-probabilities

    def recording(batch: DecisionBatch) -> np.ndarray:
        logits = sampler._logits(batch)
        actions = logits.argmax(axis=1)
        sampler._commit(batch, actions)
        logp = torch.log_softmax(torch.from_numpy(logits), dim=1).numpy()
        for r in range(len(batch)):
            seen.setdefault((batch.episode[r], batch.agent[r]), []).append(logp[r])
        return actions

    ro = env.rollout(recording, 2)
    paths = gru.Paths.pack(normalizer(ro.obs), ro.actions, ro.path_start, env.n_actions)
    with torch.no_grad():
        trained = paths.log_probs(policy).numpy()
    for p, (e, a) in enumerate(zip(ro.path_episode, ro.path_agent)):
        rows = slice(ro.path_start[p], ro.path_start[p + 1])
        np.testing.assert_allclose(np.array(seen[e, a]), trained[rows], rtol=0, atol=1e-12)
    assert len(seen) == ro.n_paths


def test_sampled_actions_are_deterministic_and_reset_per_rollout():
    torch.manual_seed(0)
    pkg = env_package("bus")
    env = pkg.make_env(pkg.BusConfig())
    policy = gru.GRUPolicy(env.obs_dim, env.n_actions)
    runs = []
    sampler = gru.GRUSampler(policy, ObsNormalizer(env.obs_dim), np.random.default_rng(2))
    for _ in range(2):  # one sampler, two rollouts: the second starts from zero states again
        sampler.rng = np.random.default_rng(2)
        runs.append(env.rollout(sampler, 2).actions)
    np.testing.assert_array_equal(*runs)


@pytest.mark.parametrize("damping", [0.0, 1e-5])
def test_finite_difference_and_exact_fisher_products_agree(damping):
    torch.manual_seed(3)
    policy = gru.GRUPolicy(4, 4)
    _, paths = bus_batch(policy)
    with torch.no_grad():
        logp_old = paths.log_probs(policy)
    theta = gru.FlatParameters(policy).get_flat()
    products = {m: gru.fisher_product(policy, paths, logp_old, m, 1e-5, damping)
                for m in ("exact", "finite-difference")}
    rng = np.random.default_rng(4)
    for _ in range(2):
        v = rng.standard_normal(len(theta))
        exact, fd = products["exact"](v), products["finite-difference"](v)
        assert np.linalg.norm(fd - exact) <= FVP_TOLERANCE * np.linalg.norm(exact)
        assert v @ exact > 0  # a Fisher matrix: positive along any direction the policy moves
    # the finite differences leave the parameters where they were
    np.testing.assert_array_equal(gru.FlatParameters(policy).get_flat(), theta)


def toy_run(tmp_path, name: str, epochs: int, **extra) -> Trainer:
    cfg = train_config("quick", "toy", epochs=epochs, batch_episodes=4, seed=3, policy="gru",
                       gru_features=(8,), gru_feature_output=4, gru_hidden=5, **extra)
    trainer = Trainer(cfg, toy.make_env(toy.ToyConfig(horizon=8)), tmp_path / name,
                      toy.ToyConfig(horizon=8))
    trainer.train()
    return trainer


@pytest.mark.parametrize("fvp", ["finite-difference", "exact"])
def test_a_resumed_gru_run_equals_one_straight_through(tmp_path, fvp):
    toy_run(tmp_path, "a", 3, gru_fvp=fvp)
    toy_run(tmp_path, "b", 2, gru_fvp=fvp)
    toy_run(tmp_path, "b", 3, gru_fvp=fvp)  # resumes from epoch 2
    ck = {n: load_checkpoint(tmp_path / n / CHECKPOINT) for n in "ab"}
    assert ck["b"]["epoch"] == 3
    assert tensors_equal(ck["a"]["policy"], ck["b"]["policy"])
    assert ck["a"]["sampler_rng"] == ck["b"]["sampler_rng"]
    frames = [pd.read_csv(tmp_path / n / "progress.csv").drop(columns=TIMING_COLUMNS)
              for n in "ab"]
    pd.testing.assert_frame_equal(*frames, check_exact=True)
    assert frames[0].accepted.sum() >= 1  # the steps moved the policy


def test_the_trained_gru_loads_and_acts_sampled_and_greedy(tmp_path):
    trainer = toy_run(tmp_path, "run", 1)
    env = toy.make_env(toy.ToyConfig(horizon=8))
    sampler = policy_from_checkpoint(tmp_path / "run" / CHECKPOINT, np.random.default_rng(0))
    assert isinstance(sampler, gru.GRUSampler)
    assert tensors_equal(sampler.policy.state_dict(), trainer.policy.state_dict())
    greedy = [env.rollout(sampler.greedy, 2, 0).actions for _ in range(2)]
    np.testing.assert_array_equal(*greedy)
    assert env.rollout(sampler, 2, 0).n_decisions > 0


@pytest.mark.parametrize("bad, param", [
    (["--policy", "lstm"], "--policy"),
    (["--policy", "gru", "--hidden", "64"], "--hidden"),
    (["--policy", "gru", "--init", "orthogonal"], "--init"),
    (["--policy", "gru", "--fvp-subsample", "0.5"], "--fvp-subsample"),
    (["--policy", "gru", "--gru-fvp", "secant"], "--gru-fvp"),
    (["--policy", "gru", "--gru-fvp-eps", "0"], "--gru-fvp-eps"),
    (["--policy", "gru", "--gru-hidden", "0"], "--gru-hidden"),
    (["--policy", "gru", "--gru-features", "0"], "--gru-features"),
    (["--gru-hidden", "16"], "--gru-hidden"),
    (["--policy", "mlp", "--gru-fvp", "exact"], "--gru-fvp"),
])
def test_bad_gru_options_exit_2_with_one_line(tmp_path, capsys, bad, param):
    out = tmp_path / "run"
    assert main(["train", "--env", "toy", "--scale", "smoke", "--out", str(out), *bad]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and param in err
    assert not out.exists()


def test_a_run_of_one_policy_never_resumes_as_the_other(tmp_path, capsys):
    opts = ["train", "--env", "toy", "--scale", "smoke", "--epochs", "1", "--horizon", "6"]
    for first, second in (("mlp", "gru"), ("gru", "mlp")):
        out = tmp_path / first
        assert main([*opts, "--policy", first, "--out", str(out)]) == 0
        before = tree_snapshot(out)
        capsys.readouterr()
        assert main([*opts, "--epochs", "2", "--policy", second, "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "policy" in err
        assert tree_snapshot(out) == before


@pytest.mark.slow
def test_cli_trains_a_gru_on_the_bus(tmp_path):
    out = tmp_path / "run"
    res = run_cli("train", "--env", "bus", "--policy", "gru", "--scale", "smoke", "--out",
                  str(out))
    assert res.returncode == 0, res.stderr
    frame = pd.read_csv(out / "progress.csv")
    assert list(frame.epoch) == [0, 1] and (frame.decisions >= 300).all()
    state = load_checkpoint(out / CHECKPOINT)
    assert state["run_config"]["train"]["policy"] == "gru"
    assert state["run_config"]["train"]["gru_fvp"] == "finite-difference"


@pytest.mark.slow
def test_the_bus_pictures_train_and_draw_the_gru(tmp_path, capsys):
    """C5's driver: the pictures train the GRU runs (resumable), pick the best by its sampled
    test return, and draw it sampled and greedy beside No Holding; a second call trains
    nothing."""
    common = ["--scale", "smoke", "--runs-dir", str(tmp_path / "runs"), "--n-jobs", "1",
              "--results-dir", str(tmp_path / "res"), "--figures-dir", str(tmp_path / "fig"),
              "--policies", "nohold", "gru", "gru-greedy"]
    assert main(["bus-arrivals", *common]) == 0
    runs = pd.read_csv(tmp_path / "res" / "bus_gru_runs.csv")
    assert list(runs.seed) == [0, 1] and runs.best.sum() == 1
    assert runs.test_return[runs.best].iloc[0] == runs.test_return.max()
    arrivals = pd.read_csv(tmp_path / "res" / "bus_arrivals.csv")
    assert set(arrivals.policy) == {"nohold", "gru", "gru-greedy"}
    trained = tree_snapshot(tmp_path / "runs")
    assert main(["bus-loads", *common]) == 0
    assert tree_snapshot(tmp_path / "runs") == trained
    loads = pd.read_csv(tmp_path / "res" / "bus_load.csv")
    assert {"gru", "gru-greedy"} <= set(loads.policy)
    capsys.readouterr()
    # the chosen run named directly, acting greedily, gives the same panel
    best = runs.run[runs.best].iloc[0]
    assert main(["bus-eval", "--policy", "gru-greedy", "--gru-run", best, "--json"]) == 0


@pytest.mark.parametrize("args, param", [
    (["bus-arrivals", "--scale", "smoke", "--policies", "nohold", "--gru-run", "runs/x"],
     "--gru-run"),
    (["bus-arrivals", "--scale", "smoke", "--policies", "gru", "--n-jobs", "0"], "--n-jobs"),
    (["bus-eval", "--policy", "mlp", "--gru-run", "runs/x"], "--gru-run"),
    (["bus-eval", "--policy", "gru"], "--gru-run"),
])
def test_bad_gru_picture_options_exit_2_with_one_line(tmp_path, capsys, args, param):
    # the pictures write into --results-dir; bus-eval writes nothing, and refuses a
    # --results-dir its policy does not read
    folders = [] if args[0] == "bus-eval" else ["--results-dir", str(tmp_path / "r")]
    assert main([*args, *folders]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"error: {param}:" in err, err
    assert not (tmp_path / "r").exists()
