"""The compiled arithmetic of the policy network (repro.learn.network): its products agree with
autograd on the same module, its forward pass is the sampler's bit for bit, and its sums do not
depend on how the batch is blocked."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from torch.nn.utils import parameters_to_vector

from repro.learn import network
from repro.learn.network import TanhMLP
from repro.learn.policy import CategoricalPolicy, ObsNormalizer, Sampler


def problem(seed: int, hidden: tuple[int, ...], n: int = 40, obs_dim: int = 3, n_actions: int = 4):
    torch.manual_seed(seed)
    policy = CategoricalPolicy(obs_dim, n_actions, hidden).double()  # float64: tight comparisons
    with torch.no_grad():
        policy.net[-1].weight.mul_(50.0)  # far from uniform, so the products are not trivial
    obs = torch.randn(n, obs_dim, dtype=torch.float64)
    return policy, obs


def as_function(policy: CategoricalPolicy, obs: torch.Tensor):
    """theta -> logits (N, n_actions) by autograd's own arithmetic."""
    names = [name for name, _ in policy.net.named_parameters()]
    shapes = [p.shape for p in policy.net.parameters()]

    def logits(theta: torch.Tensor) -> torch.Tensor:
        pieces = torch.split(theta, [s.numel() for s in shapes])
        params = {k: p.view(s) for k, p, s in zip(names, pieces, shapes)}
        return torch.func.functional_call(policy.net, params, (obs,))

    return logits


HIDDEN = [(5,), (6, 4), (4, 5, 3)]


@pytest.mark.parametrize("hidden", HIDDEN)
def test_forward_is_the_modules(hidden):
    policy, obs = problem(0, hidden)
    fwd = TanhMLP(policy.net).forward(obs.numpy())
    with torch.no_grad():
        np.testing.assert_allclose(fwd.log_probs(), policy(obs).numpy(), rtol=0, atol=1e-12)


@pytest.mark.parametrize("hidden", HIDDEN)
@pytest.mark.parametrize("n", [40, 1500])  # one chunk and two, both padded
def test_jacobian_products_match_autograd(hidden, n):
    policy, obs = problem(1, hidden, n=n)
    net = TanhMLP(policy.net)
    theta = parameters_to_vector(policy.parameters()).detach()
    f = as_function(policy, obs)
    v = torch.randn(len(theta), dtype=torch.float64)
    g = torch.randn(len(obs), policy.net[-1].out_features, dtype=torch.float64)
    _, jv = torch.func.jvp(f, (theta,), (v,))
    _, pullback = torch.func.vjp(f, theta)
    (jtg,) = pullback(g)
    fwd = net.forward(obs.numpy())
    np.testing.assert_allclose(net.jvp(fwd, v.numpy()), jv.numpy(), rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(net.vjp(fwd, g.numpy()), jtg.numpy(), rtol=1e-10, atol=1e-10)
    # on a subset of the batch, the products are those of the subset's inputs
    rows = np.array([0, 3, 7])
    np.testing.assert_allclose(net.jvp(fwd.rows(rows), v.numpy()), jv.numpy()[rows], rtol=1e-10,
                               atol=1e-10)


@pytest.mark.parametrize("hidden", [(32,), (32, 32)])
def test_forward_is_the_samplers_bit_for_bit(hidden):
    """float32, as in training: the step differentiates the logits the batch was sampled with."""
    torch.manual_seed(3)
    policy = CategoricalPolicy(7, 5, hidden, init="xavier")
    obs = np.random.default_rng(3).normal(size=(300, 7))
    sampler = Sampler(policy, ObsNormalizer(7, eps=0.0), np.random.default_rng(0))  # scale 1
    logits = TanhMLP(policy.net).forward(obs.astype(np.float32)).logits[:, :300].T
    assert logits.dtype == np.float32
    np.testing.assert_array_equal(logits, sampler.logits(obs))


def test_fisher_product_is_the_jacobian_products_and_blocking_free(monkeypatch):
    """The fused product is J' (M J v) / N of the separate products; and the blocks a forward
    pass and the forward-mode product are computed in change no bit (their sums are each
    decision's own)."""
    policy, obs = problem(4, (6, 4), n=700)
    net = TanhMLP(policy.net)
    fwd = net.forward(obs.numpy())
    p = np.exp(fwd.log_probs())
    v = np.random.default_rng(4).normal(size=net.size)
    jv = net.jvp(fwd, v)
    u = p * (jv - (p * jv).sum(axis=1, keepdims=True)) / len(p)
    got = net.fisher_product(fwd, network.probabilities(fwd), v)
    np.testing.assert_allclose(got, net.vjp(fwd, u), rtol=1e-12, atol=1e-14)


def test_flat_parameters_are_parameters_to_vector_and_set_in_place():
    policy, _ = problem(2, (6, 4))
    net = TanhMLP(policy.net)
    theta = parameters_to_vector(policy.parameters()).detach().clone()
    np.testing.assert_array_equal(net.get_flat(), theta.numpy())
    moved = theta + torch.arange(len(theta), dtype=torch.float64)
    net.set_flat(moved.numpy())
    np.testing.assert_array_equal(parameters_to_vector(policy.parameters()).detach().numpy(),
                                  moved.numpy())
    np.testing.assert_array_equal(net.get_flat(), moved.numpy())  # the arrays follow
