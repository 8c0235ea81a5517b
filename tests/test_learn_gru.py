"""The recurrent policy (``--policy gru``): its sampler threads each agent's state as training
does, its two Fisher-vector products agree, a run resumes exactly, bad options are refused in one
line, and the real entry points run it."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import torch
from torch.nn.utils import parameters_to_vector

from repro.cli import main
from repro.core.rollout import DecisionBatch
from repro.envs import env_package, toy
from repro.learn import gru, gru_kernel
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
TOLERANCE = 1e-10
"""Relative difference allowed between a compiled product and autograd's on the same float64
module (they differ in summation order only: about 1e-15)."""


def bus_batch(policy: gru.GRUPolicy, episodes: int = 2):
    pkg = env_package("bus")
    env = pkg.make_env(pkg.BusConfig())
    sampler = gru.GRUSampler(policy, ObsNormalizer(env.obs_dim), np.random.default_rng(0))
    ro = env.rollout(sampler, episodes)
    return ro, gru.Paths.pack(ro.obs, ro.actions, ro.path_start, env.n_actions)


class Reference:
    """A batch of paths run through the torch module by autograd (``GRUPolicy.sequence`` on the
    paths padded to (P, T)): logits (D, n_actions) in the batch's order."""

    def __init__(self, policy: gru.GRUPolicy, z, actions, path_start):
        lengths = np.diff(path_start)
        self.p = np.repeat(np.arange(len(lengths)), lengths)
        self.t = np.arange(len(z)) - np.repeat(path_start[:-1], lengths)
        prev = np.where(self.t > 0, np.concatenate([[-1], actions[:-1]]), -1)
        x = np.zeros((len(lengths), lengths.max(), z.shape[1] + policy.n_actions))
        x[self.p, self.t] = gru.inputs(z, prev, policy.n_actions)
        self.x, self.policy = torch.from_numpy(x), policy
        self.params = list(policy.parameters())

    def logits(self) -> torch.Tensor:
        return self.policy.sequence(self.x)[self.p, self.t]

    def grad(self, scalar: torch.Tensor, **kw) -> torch.Tensor:
        return torch.cat([g.reshape(-1) for g in torch.autograd.grad(scalar, self.params, **kw)])

    def jvp(self, v: np.ndarray) -> np.ndarray:
        """J v by the double-vjp trick (J v = d/du of (J' u) . v)."""
        logits = self.logits()
        u = torch.zeros_like(logits, requires_grad=True)
        pulled = self.grad((logits * u).sum(), create_graph=True)
        return torch.autograd.grad(pulled @ torch.from_numpy(v), u)[0].detach().numpy()

    def fisher(self, v: np.ndarray) -> np.ndarray:
        """The Hessian of the mean KL(current || theta) at the current parameters, times v, by
        double backward."""
        with torch.no_grad():
            logp_old = torch.log_softmax(self.logits(), dim=1)
        kl = (logp_old.exp() * (logp_old - torch.log_softmax(self.logits(), dim=1))).sum(1).mean()
        g = self.grad(kl, create_graph=True)
        return self.grad(g @ torch.from_numpy(v)).numpy()


def ragged(seed: int, lengths: list[int], obs_dim: int = 3, n_actions: int = 4, hidden: int = 5,
           features: tuple[int, ...] = (6, 7), feature_output: int = 4):
    """A small float64 gru policy far from uniform and a batch of paths of ``lengths``."""
    torch.manual_seed(seed)
    policy = gru.GRUPolicy(obs_dim, n_actions, hidden, features, feature_output)
    with torch.no_grad():
        policy.out.weight.mul_(5.0)
        policy.gru.h_weight.mul_(2.0)
    rng = np.random.default_rng(seed)
    path_start = np.concatenate([[0], np.cumsum(lengths)])
    z = rng.standard_normal((path_start[-1], obs_dim))
    actions = rng.integers(0, n_actions, path_start[-1])
    return policy, z, actions, path_start


def flat(policy: gru.GRUPolicy) -> np.ndarray:
    """The module's parameters as torch lays them out (``parameters_to_vector``)."""
    return parameters_to_vector(policy.parameters()).detach().numpy()


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


LENGTHS = {"ragged": [5, 1, 3, 5, 2, 7, 1], "one decision": [1], "equal": [4, 4, 4],
           "one path": [9], "wide": [2] * 700 + [1] * 500 + [3]}
"""Batches of paths: of different lengths, a single path of length 1, a step wider than a chunk
of columns (1,201 paths at the first step)."""


def test_paths_are_packed_step_major_longest_first():
    _, z, actions, path_start = ragged(0, [2, 3, 1, 3])
    paths = gru.Paths.pack(z, actions, path_start, 4)
    np.testing.assert_array_equal(paths.offsets, [0, 4, 7, 9])
    # ranks by length, ties in path order: path 1, path 3, path 0, path 2
    np.testing.assert_array_equal(paths.column, [2, 6, 0, 4, 7, 3, 1, 5, 8])
    np.testing.assert_array_equal(paths.column[paths.order], np.arange(9))
    assert paths.x.shape == (7, 1024) and not paths.x[:, 9:].any()
    np.testing.assert_array_equal(paths.x[:3, paths.column].T, z)
    assert paths.x[3:, paths.column[[0, 2, 5, 6]]].sum() == 0  # no previous action at step 0
    assert paths.x[3 + actions[0], paths.column[1]] == 1.0


@pytest.mark.parametrize("name", LENGTHS)
def test_compiled_products_match_autograd(name):
    policy, z, actions, path_start = ragged(1, LENGTHS[name])
    ref = Reference(policy, z, actions, path_start)
    paths = gru.Paths.pack(z, actions, path_start, policy.n_actions)
    net = gru.GRUNet(policy)
    np.testing.assert_array_equal(net.get_flat(), flat(policy))
    fwd = net.forward(paths)
    logits = ref.logits()
    np.testing.assert_allclose(fwd.logits[:, paths.column].T, logits.detach().numpy(), rtol=0,
                               atol=1e-13)
    np.testing.assert_allclose(fwd.log_probs()[paths.column],
                               torch.log_softmax(logits, 1).detach().numpy(), rtol=0, atol=1e-13)
    rng = np.random.default_rng(2)
    g = rng.standard_normal(logits.shape)
    expected = ref.grad((logits * torch.from_numpy(g)).sum()).numpy()
    got = net.gradient(fwd, gru.columns(g[paths.order], paths.x.shape[1]))
    assert relative(got, expected) < TOLERANCE
    v = rng.standard_normal(net.size)
    assert relative(net.jvp(fwd, v)[:, paths.column].T, ref.jvp(v)) < TOLERANCE
    fisher = ref.fisher(v)
    exact = gru.fisher_product(net, fwd, "exact", 1e-5, 0.0)(v)
    assert relative(exact, fisher) < TOLERANCE
    fd = gru.fisher_product(net, fwd, "finite-difference", 1e-5, 0.0)(v)
    assert relative(fd, fisher) < FVP_TOLERANCE
    np.testing.assert_array_equal(net.get_flat(), flat(policy))


@pytest.mark.parametrize("name", ["ragged", "wide"])
def test_the_sampler_computes_the_training_pass_logits_bit_for_bit(name):
    """Row by row, each path's decisions in turn, the sampler's step gives the logits of the
    batch's pass, bit for bit, and the module's step up to rounding."""
    policy, z, actions, path_start = ragged(3, LENGTHS[name])
    fwd = gru.GRUNet(policy).forward(gru.Paths.pack(z, actions, path_start, policy.n_actions))
    weights = gru._row_weights(policy)
    x = gru.inputs(z, np.where(np.isin(np.arange(len(z)), path_start), -1,
                               np.concatenate([[-1], actions[:-1]])), policy.n_actions)
    logits = np.empty((len(z), policy.n_actions))
    for p in range(len(path_start) - 1):
        h = np.zeros((1, policy.hidden))
        for d in range(path_start[p], path_start[p + 1]):
            h_new = np.empty_like(h)
            gru_kernel.step_rows(x[d:d + 1], h, *weights, logits[d:d + 1], h_new)
            with torch.no_grad():
                step, h_torch = policy.step(torch.from_numpy(x[d:d + 1]), torch.from_numpy(h))
            np.testing.assert_allclose(logits[d:d + 1], step.numpy(), rtol=0, atol=1e-13)
            np.testing.assert_allclose(h_new, h_torch.numpy(), rtol=0, atol=1e-13)
            h = h_new
    paths = gru.Paths.pack(z, actions, path_start, policy.n_actions)
    np.testing.assert_array_equal(fwd.logits[:, paths.column].T, logits)


def test_the_sampler_runs_each_agents_state_over_its_own_decisions():
    """The logits the sampler acted on are those the training pass computes for the batch, bit
    for bit: each agent's state runs over its own decisions, as in training."""
    torch.manual_seed(0)
    pkg = env_package("bus")
    env = pkg.make_env(pkg.BusConfig())
    policy = gru.GRUPolicy(env.obs_dim, env.n_actions)
    normalizer = ObsNormalizer(env.obs_dim)
    sampler = gru.GRUSampler(policy, normalizer, np.random.default_rng(1))
    seen = {}  # (episode, agent) -> per decision the sampler's logits

    def recording(batch: DecisionBatch) -> np.ndarray:
        logits = sampler._logits(batch)
        actions = logits.argmax(axis=1)
        sampler._commit(batch, actions)
        for r in range(len(batch)):
            seen.setdefault((batch.episode[r], batch.agent[r]), []).append(logits[r])
        return actions

    ro = env.rollout(recording, 2)
    paths = gru.Paths.pack(normalizer(ro.obs), ro.actions, ro.path_start, env.n_actions)
    trained = gru.GRUNet(policy).forward(paths).logits[:, paths.column].T
    for p, (e, a) in enumerate(zip(ro.path_episode, ro.path_agent)):
        rows = slice(ro.path_start[p], ro.path_start[p + 1])
        np.testing.assert_array_equal(np.array(seen[e, a]), trained[rows])
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
    net = gru.GRUNet(policy)
    fwd = net.forward(paths)
    theta = net.get_flat()
    products = {m: gru.fisher_product(net, fwd, m, 1e-5, damping)
                for m in ("exact", "finite-difference")}
    rng = np.random.default_rng(4)
    for _ in range(2):
        v = rng.standard_normal(len(theta))
        exact, fd = products["exact"](v), products["finite-difference"](v)
        assert np.linalg.norm(fd - exact) <= FVP_TOLERANCE * np.linalg.norm(exact)
        assert v @ exact > 0  # a Fisher matrix: positive along any direction the policy moves
    # the finite differences leave the parameters where they were, the module's too
    np.testing.assert_array_equal(net.get_flat(), theta)
    np.testing.assert_array_equal(flat(policy), theta)


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
