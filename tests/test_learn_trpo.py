"""The pieces of the TRPO step: conjugate gradient, Fisher-vector product, line search, KL bound."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from torch.nn.utils import parameters_to_vector, vector_to_parameters

from repro.learn.network import TanhMLP
from repro.learn.policy import CategoricalPolicy
from repro.learn.trpo import (conjugate_gradient, fisher_vector_product, line_search, mean_kl,
                              normalize, surrogate_and_kl, trpo_step)

DTYPE = torch.float64

TRPO_KW = dict(max_kl=0.01, cg_iters=10, cg_damping=1e-5, backtrack_ratio=0.8, max_backtracks=15)


def tiny_problem(seed: int, n: int = 64, obs_dim: int = 3, n_actions: int = 4, hidden=(5,)):
    torch.manual_seed(seed)
    # float64 (the trainer's networks are float32) so that comparisons can be tight
    policy = CategoricalPolicy(obs_dim, n_actions, hidden).double()
    # a larger output gain than the default, so the policy is far from uniform and F non-trivial
    with torch.no_grad():
        policy.net[-1].weight.mul_(100.0)
    g = torch.Generator().manual_seed(seed)
    obs = torch.randn(n, obs_dim, generator=g, dtype=DTYPE)
    actions = torch.randint(0, n_actions, (n,), generator=g)
    adv = torch.as_tensor(normalize(torch.randn(n, generator=g, dtype=DTYPE).numpy()))
    return policy, obs, actions, adv


def logp_of(policy: CategoricalPolicy, obs: torch.Tensor) -> np.ndarray:
    """The module's log-probabilities, (N, n_actions) like the step's."""
    with torch.no_grad():
        return policy(obs).numpy()


def flat(policy: CategoricalPolicy) -> np.ndarray:
    return parameters_to_vector(policy.parameters()).detach().numpy().copy()


def step(policy, obs, actions, adv, **kw):
    return trpo_step(TanhMLP(policy.net), obs.numpy(), actions.numpy(), adv.numpy(),
                     **{**TRPO_KW, **kw})


def test_conjugate_gradient_solves_spd_system():
    rng = np.random.default_rng(0)
    m = rng.normal(size=(12, 12))
    a = m @ m.T + 0.5 * np.eye(12)
    b = rng.normal(size=12)
    x = conjugate_gradient(lambda v: a @ v, b, iters=40, residual_tol=1e-24)
    np.testing.assert_allclose(a @ x, b, atol=1e-8)
    # fewer iterations: an approximation whose residual is smaller than b's
    x3 = conjugate_gradient(lambda v: a @ v, b, iters=3)
    assert np.linalg.norm(a @ x3 - b) < np.linalg.norm(b)


@pytest.mark.parametrize("seed", [0, 1])
def test_fvp_matches_explicit_hessian_of_mean_kl(seed):
    policy, obs, _, _ = tiny_problem(seed)
    theta0 = parameters_to_vector(policy.parameters()).detach().clone()
    with torch.no_grad():
        logp_old = policy(obs)

    def kl_of(theta: torch.Tensor) -> torch.Tensor:
        """The mean KL by autograd's own arithmetic, sample-major, independent of the step's."""
        params, i = {}, 0
        for name, p in policy.named_parameters():
            params[name] = theta[i:i + p.numel()].view_as(p)
            i += p.numel()
        logp = torch.func.functional_call(policy, params, (obs,))
        return (logp_old.exp() * (logp_old - logp)).sum(dim=1).mean()

    hessian = torch.autograd.functional.hessian(kl_of, theta0)
    assert torch.linalg.norm(hessian) > 1e-3  # the comparison is not trivially 0 == 0
    damping = 0.1
    net = TanhMLP(policy.net)
    fvp = fisher_vector_product(net, net.forward(obs.numpy()), damping)
    eye = np.eye(len(theta0))
    fisher = np.stack([fvp(e) for e in eye], axis=1)
    np.testing.assert_allclose(fisher, hessian.numpy() + damping * eye, atol=1e-10)


@pytest.mark.parametrize("seed", range(5))
def test_accepted_steps_respect_kl_bound(seed):
    policy, obs, actions, adv = tiny_problem(seed)
    logp_old = logp_of(policy, obs)
    stats = step(policy, obs, actions, adv)
    kl = mean_kl(logp_old, logp_of(policy, obs))
    assert kl == pytest.approx(stats.kl, abs=1e-12)
    if stats.accepted:
        assert 0 < kl <= TRPO_KW["max_kl"]
        assert stats.surrogate_after > stats.surrogate_before
    else:
        assert kl == 0.0


def test_line_search_rejects_kl_violation_and_restores_parameters():
    policy, obs, actions, adv = tiny_problem(3)
    net = TanhMLP(policy.net)
    theta0 = flat(policy)
    logp_old = logp_of(policy, obs)
    grad_dir = np.random.default_rng(1).normal(size=len(theta0))
    rows = np.arange(len(actions))

    def evaluate():
        logp = logp_of(policy, obs)
        surr = np.exp(logp[rows, actions] - logp_old[rows, actions]) * adv.numpy()
        return float(surr.mean()), mean_kl(logp_old, logp)

    surr0 = evaluate()[0]
    seen = []

    def recording_evaluate():
        out = evaluate()
        seen.append(out[1])
        return out

    # a huge step with too few backtracks to come back inside the trust region
    accepted, backtracks, _, kl = line_search(net, recording_evaluate, 1e3 * grad_dir,
                                              surr0 - 1e9, 0.01, 0.8, 3)
    assert not accepted and backtracks == 3 and kl == 0.0
    assert min(seen) > 0.01  # every try violated the bound ...
    np.testing.assert_array_equal(flat(policy), theta0)  # ... and nothing moved
    # the same step, allowed to shrink far enough, is accepted inside the bound
    accepted, backtracks, _, kl = line_search(net, evaluate, 1e3 * grad_dir, surr0 - 1e9,
                                              0.01, 0.5, 60)
    assert accepted and backtracks > 3 and kl <= 0.01
    vector_to_parameters(torch.from_numpy(theta0), policy.parameters())


def test_surrogate_and_kl_are_the_modules():
    """What a line-search trial evaluates: the surrogate and mean KL of the network's current
    parameters against the pass at the old ones, computed here through the torch module."""
    policy, obs, actions, adv = tiny_problem(7)
    net = TanhMLP(policy.net)
    logp_old = logp_of(policy, obs)
    obs, actions, adv = obs.numpy(), actions.numpy(), adv.numpy()
    old = net.forward(obs)
    surr, kl = surrogate_and_kl(net, old, actions, adv)
    assert surr == pytest.approx(float(adv.mean()), abs=1e-12) and kl == pytest.approx(0, abs=1e-12)
    net.set_flat(net.get_flat() + 0.01 * np.random.default_rng(7).normal(size=net.size))
    logp = logp_of(policy, torch.from_numpy(obs))
    rows = np.arange(len(actions))
    taken = logp[rows, actions] - logp_old[rows, actions]
    surr, kl = surrogate_and_kl(net, old, actions, adv)
    assert surr == pytest.approx(float((np.exp(taken) * adv).mean()), rel=1e-12)
    expected_kl = float((np.exp(logp_old) * (logp_old - logp)).sum(axis=1).mean())
    assert kl == pytest.approx(expected_kl, rel=1e-9) and kl > 0


def test_line_search_rejects_step_that_lowers_surrogate():
    policy, obs, actions, adv = tiny_problem(4)
    theta0 = flat(policy)
    accepted, _, _, _ = line_search(TanhMLP(policy.net), lambda: (0.0, 0.0),
                                    np.ones_like(theta0), 1.0, 0.01, 0.8, 5)
    assert not accepted
    np.testing.assert_array_equal(flat(policy), theta0)


def test_step_improves_surrogate_along_natural_gradient():
    policy, obs, actions, adv = tiny_problem(5, n=256)
    stats = step(policy, obs, actions, adv)
    assert stats.accepted and stats.surrogate_after > stats.surrogate_before
    # the quadratic model sizes the first try to the bound: the accepted KL is close to max_kl
    assert stats.kl > 0.2 * TRPO_KW["max_kl"]
    assert 0 < stats.entropy <= np.log(4) + 1e-12


def test_fvp_subsample_all_rows_is_the_full_step_and_a_subsample_keeps_the_kl_bound():
    """fvp_rows = every row reproduces the full-batch update exactly; a subsample changes the step
    (so the option is live) yet the line search still enforces the KL bound on the whole batch."""
    results = {}
    for name, rows in (("none", None), ("all", np.arange(64)), ("half", np.arange(0, 64, 2))):
        policy, obs, actions, adv = tiny_problem(3)
        logp_old = logp_of(policy, obs)
        stats = step(policy, obs, actions, adv, fvp_rows=rows)
        assert mean_kl(logp_old, logp_of(policy, obs)) <= TRPO_KW["max_kl"] + 1e-12
        results[name] = (flat(policy), stats.accepted)
    assert all(accepted for _, accepted in results.values())
    np.testing.assert_array_equal(results["none"][0], results["all"][0])
    assert not np.allclose(results["none"][0], results["half"][0])


def test_surrogate_gradient_is_autograds():
    from repro.learn.trpo import surrogate_gradient

    policy, obs, actions, adv = tiny_problem(6)
    logp = policy(obs)
    taken = logp.gather(1, actions[:, None])[:, 0]
    surrogate = (torch.exp(taken - taken.detach()) * adv).mean()
    grads = torch.autograd.grad(surrogate, list(policy.parameters()))
    expected = torch.cat([g.reshape(-1) for g in grads])
    net = TanhMLP(policy.net)
    fwd = net.forward(obs.numpy())
    got = surrogate_gradient(net, fwd, actions.numpy(), adv.numpy())
    assert torch.linalg.norm(expected) > 1e-3
    np.testing.assert_allclose(got, expected.numpy(), rtol=1e-10, atol=1e-12)
