"""One spec of the policy network, and each form of it checked against the spec layer by layer:
the torch module (:func:`repro.learn.policy.mlp`), the forward pass the derivative products reuse
(:class:`repro.learn.network.TanhMLP`), and the sampler's evaluation, row by row in compiled code
(:func:`repro.learn.policy_kernel.logits_row`, :meth:`Sampler.logits`); for hidden sizes the
config allows and both initialisations."""

from __future__ import annotations

import itertools
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from torch import nn

from repro.learn.config import INITS
from repro.learn.network import TanhMLP
from repro.learn.policy import (BLOCK, BLOCK_MIN, CategoricalPolicy, ObsNormalizer, Sampler,
                                 _logits_rows)
from repro.learn.policy_kernel import logits_row

OBS_DIM, N_ACTIONS, ROWS = 7, 5, 64
HIDDEN = [(32,), (32, 32), (5,), (4, 6, 3)]
"""The authors' learner's (32,), the suite's (32, 32), and others (the config allows any)."""


def spec(layers: list[tuple[np.ndarray, np.ndarray]], x: np.ndarray) -> list[np.ndarray]:
    """The network, in float64: every layer is ``z = x W' + b`` with ``W`` (outputs, inputs) as
    torch's ``Linear`` holds it, and every layer but the last passes tanh(z) on. Returns each
    layer's z."""
    pre = []
    for w, b in layers:
        z = x @ w.T + b
        pre.append(z)
        x = np.tanh(z)
    return pre


def network(hidden: tuple[int, ...], init: str, seed: int):
    """A policy as the trainer makes it, its normaliser fitted to observations of mixed scales,
    and normalised inputs (float32, as the sampler computes them)."""
    torch.manual_seed(seed)
    policy = CategoricalPolicy(OBS_DIM, N_ACTIONS, hidden, init=init)
    rng = np.random.default_rng(seed)
    norm = ObsNormalizer(OBS_DIM)
    norm.update(rng.normal(2.0, 5.0, size=(300, OBS_DIM)))
    obs = rng.normal(2.0, 5.0, size=(ROWS, OBS_DIM))
    x = ((obs - norm.mean) / np.sqrt(norm.var + norm.eps)).astype(np.float32)
    return policy, norm, obs, x


def parameters(policy: CategoricalPolicy) -> list[tuple[np.ndarray, np.ndarray]]:
    return [(m.weight.detach().double().numpy(), m.bias.detach().double().numpy())
            for m in policy.net if isinstance(m, nn.Linear)]


CASES = list(itertools.product(HIDDEN, INITS))


@pytest.mark.parametrize("hidden, init", CASES)
def test_the_torch_module_is_the_spec_layer_by_layer(hidden, init):
    policy, _, _, x = network(hidden, init, seed=1)
    layers = parameters(policy)
    assert [w.shape for w, _ in layers] == [
        (b, a) for a, b in zip((OBS_DIM, *hidden), (*hidden, N_ACTIONS))]
    pre = spec(layers, x.astype(np.float64))
    outputs, h = [], torch.as_tensor(x)
    with torch.no_grad():
        for module in policy.net:
            h = module(h)
            outputs.append(h.double().numpy())
    # Linear, activation, ..., Linear: each Linear gives z, each activation tanh(z)
    assert len(outputs) == 2 * len(hidden) + 1
    for k, z in enumerate(pre):
        np.testing.assert_allclose(outputs[2 * k], z, rtol=1e-5, atol=1e-6)
        if k < len(hidden):
            np.testing.assert_allclose(outputs[2 * k + 1], np.tanh(z), rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("hidden, init", CASES)
def test_the_derivative_products_forward_pass_is_the_spec_layer_by_layer(hidden, init):
    policy, _, _, x = network(hidden, init, seed=2)
    policy = policy.double()  # float64: the spec's arithmetic up to summation order
    pre = spec(parameters(policy), x.astype(np.float64))
    fwd = TanhMLP(policy.net).forward(x.astype(np.float64))
    assert len(fwd.hidden) == len(hidden)
    n = len(x)
    for k, h in enumerate(fwd.hidden):  # feature-major
        np.testing.assert_allclose(h[:, :n].T, np.tanh(pre[k]), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(fwd.logits[:, :n].T, pre[-1], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("hidden, init", CASES)
def test_the_samplers_evaluation_is_the_spec_layer_by_layer(hidden, init):
    """The first k layers of the sampler's network give layer k's z: its last layer takes no
    tanh. So the row-by-row evaluation is checked on every prefix of the network, and the
    sampler's logits on the whole of it."""
    policy, norm, obs, x = network(hidden, init, seed=3)
    pre = spec(parameters(policy), x.astype(np.float64))
    sampler = Sampler(policy, norm, np.random.default_rng(0))
    for k, z in enumerate(pre):
        weights, biases = sampler.weights[:k + 1], sampler.biases[:k + 1]
        rows = np.stack([logits_row(o, weights, biases, sampler.mean, sampler.scale)
                         for o in obs])
        np.testing.assert_allclose(rows, z, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(sampler.logits(obs), pre[-1], rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("hidden, init", CASES)
def test_a_round_in_blocks_gives_the_bits_of_the_row_by_row_evaluation(hidden, init):
    """A round of BLOCK_MIN rows or more is evaluated in blocks, a smaller one row by row: the
    logits and the actions are the same bits either way, at the threshold, across blocks, and for
    observations far outside the normaliser's range (saturated units)."""
    policy, norm, _, _ = network(hidden, init, seed=5)
    sampler = Sampler(policy, norm, np.random.default_rng(0))
    rng = np.random.default_rng(6)
    n = 2 * BLOCK + 3
    obs = rng.normal(2.0, 5.0, size=(n, OBS_DIM)) * rng.choice([1.0, 1e3], size=(n, 1))
    u = rng.random(n)
    rows = _logits_rows(obs, sampler.weights, sampler.biases, sampler.mean, sampler.scale)
    one_by_one = np.array([sampler.act(SimpleNamespace(obs=obs[r:r + 1]), u[r:r + 1])[0]
                           for r in range(n)])
    assert len(set(one_by_one)) > 1
    for size in (BLOCK_MIN - 1, BLOCK_MIN, BLOCK + 1, n):
        assert sampler.logits(obs[:size]).tobytes() == rows[:size].tobytes()
        actions = sampler.act(SimpleNamespace(obs=obs[:size]), u[:size])
        np.testing.assert_array_equal(actions, one_by_one[:size])


def test_the_spec_can_tell_another_activation():
    """A network with another activation fails the comparison: the spec is not vacuous."""
    policy, _, _, x = network((32,), "xavier", seed=4)
    layers = parameters(policy)
    relu = np.maximum(x.astype(np.float64) @ layers[0][0].T + layers[0][1], 0.0)
    other = relu @ layers[1][0].T + layers[1][1]
    assert not np.allclose(other, spec(layers, x.astype(np.float64))[-1], rtol=1e-5, atol=1e-6)
