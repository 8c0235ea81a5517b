"""The hand-written derivatives of the policy network agree with autograd on the same module."""

from __future__ import annotations

import pytest
import torch
from torch.nn.utils import parameters_to_vector

from repro.learn.network import TanhMLP, log_softmax
from repro.learn.policy import CategoricalPolicy


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
    fwd = TanhMLP(policy.net).forward(obs)
    with torch.no_grad():
        torch.testing.assert_close(log_softmax(fwd.logits).T, policy(obs), rtol=0, atol=1e-12)


@pytest.mark.parametrize("hidden", HIDDEN)
def test_jacobian_products_match_autograd(hidden):
    policy, obs = problem(1, hidden)
    net = TanhMLP(policy.net)
    theta = parameters_to_vector(policy.parameters()).detach()
    f = as_function(policy, obs)
    v = torch.randn(len(theta), dtype=torch.float64)
    g = torch.randn(policy.net[-1].out_features, len(obs), dtype=torch.float64)
    _, jv = torch.func.jvp(f, (theta,), (v,))
    _, pullback = torch.func.vjp(f, theta)
    (jtg,) = pullback(g.T)
    fwd = net.forward(obs)
    torch.testing.assert_close(net.jvp(fwd, v), jv.T, rtol=1e-10, atol=1e-10)
    torch.testing.assert_close(net.vjp(fwd, g), jtg, rtol=1e-10, atol=1e-10)
    # on a subset of the batch, the products are those of the subset's inputs
    rows = torch.tensor([0, 3, 7])
    torch.testing.assert_close(net.jvp(fwd.rows(rows), v), jv.T[:, rows], rtol=1e-10, atol=1e-10)


def test_flat_parameters_are_parameters_to_vector_and_set_in_place():
    policy, _ = problem(2, (6, 4))
    net = TanhMLP(policy.net)
    theta = parameters_to_vector(policy.parameters()).detach().clone()
    torch.testing.assert_close(net.get_flat(), theta, rtol=0, atol=0)
    moved = theta + torch.arange(len(theta), dtype=torch.float64)
    net.set_flat(moved)
    torch.testing.assert_close(parameters_to_vector(policy.parameters()).detach(), moved,
                               rtol=0, atol=0)
