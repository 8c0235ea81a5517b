"""The policy evaluated row by row in compiled code (repro.learn.policy_kernel) against numpy, torch
and the sampler."""

from __future__ import annotations

import copy

import numpy as np
import torch
from numba import njit

from repro.core.rollout import DecisionBatch
from repro.learn.policy import CategoricalPolicy, ObsNormalizer, Sampler
from repro.learn.policy_kernel import act_row, logits_row, tanh32


@njit  # not cached: numba's cache would not see a change of tanh32's file
def _tanh_all(v, out):
    for i in range(len(v)):
        out[i] = tanh32(v[i])


def test_tanh32_is_numpys_float64_tanh_rounded_to_float32():
    rng = np.random.default_rng(0)
    v = np.concatenate([
        np.linspace(-12.0, 12.0, 2_000_001),
        rng.standard_normal(2_000_000) * 3.0,
        10.0 ** rng.uniform(-40.0, 1.5, 1_000_000) * rng.choice([-1.0, 1.0], 1_000_000),
        [0.0, -0.0, 1e-3, -1e-3, 10.0, -10.0, np.inf, -np.inf],
    ]).astype(np.float32)
    v = np.concatenate([v, np.nextafter(v[-8:-2], np.float32(np.inf)),
                        np.nextafter(v[-8:-2], np.float32(-np.inf))])  # both sides of switches
    out = np.empty_like(v)
    _tanh_all(v, out)
    expected = np.tanh(v.astype(np.float64)).astype(np.float32)
    np.testing.assert_array_equal(out.view(np.int32), expected.view(np.int32))  # bits, signs too
    nan = np.empty(1, np.float32)
    _tanh_all(np.array([np.nan], np.float32), nan)
    assert np.isnan(nan[0])


def _policy(obs_dim: int, n_actions: int, hidden: tuple[int, ...],
            seed: int) -> tuple[CategoricalPolicy, Sampler]:
    torch.manual_seed(seed)
    policy = CategoricalPolicy(obs_dim, n_actions, hidden)
    with torch.no_grad():
        policy.net[-1].weight.mul_(100.0)  # far from uniform, so that the logits matter
    norm = ObsNormalizer(obs_dim)
    norm.update(np.random.default_rng(seed).normal(2.0, 5.0, size=(500, obs_dim)))
    return policy, Sampler(policy, norm, np.random.default_rng(seed))


def test_logits_row_is_the_network():
    for hidden in [(32, 32), (16,), (8, 8, 8)]:
        policy, sampler = _policy(7, 5, hidden, seed=len(hidden))
        obs = np.random.default_rng(1).normal(2.0, 5.0, size=(200, 7))
        c = sampler
        rows = np.stack([logits_row(o, c.weights, c.biases, c.mean, c.scale) for o in obs])
        # the reference: the torch module in float64 on the normalised observations
        with torch.no_grad():
            expected = copy.deepcopy(policy.net).double()(
                torch.as_tensor((obs - c.mean) * c.scale)).numpy()
        assert rows.dtype == np.float32
        np.testing.assert_allclose(rows, expected, rtol=1e-5, atol=1e-5)


def batch(obs: np.ndarray) -> DecisionBatch:
    m = len(obs)
    return DecisionBatch(obs=obs, episode=np.arange(m), agent=np.zeros(m, np.int64),
                         index=np.zeros(m, np.int64))


def test_rounds_of_any_size_sample_as_rows_do():
    """Rounds of a few rows and one large round draw the same uniforms in the same order and give
    the same actions, and the sampler's logits are logits_row's, bit for bit."""
    rows_per_round = 16
    obs = np.random.default_rng(2).normal(2.0, 5.0, size=(rows_per_round * 300, 7))
    small_rounds = _policy(7, 5, (32, 32), seed=3)[1]
    one_round = _policy(7, 5, (32, 32), seed=3)[1]
    small = np.concatenate([small_rounds(batch(obs[i:i + rows_per_round]))
                            for i in range(0, len(obs), rows_per_round)])
    large = one_round(batch(obs))
    assert len(np.unique(large)) == 5
    np.testing.assert_array_equal(small, large)
    assert small_rounds.rng.random() == one_round.rng.random()
    c = one_round
    rows = np.stack([logits_row(o, c.weights, c.biases, c.mean, c.scale) for o in obs])
    np.testing.assert_array_equal(one_round.logits(obs).view(np.int32), rows.view(np.int32))
    ref = _policy(7, 5, (32, 32), seed=3)[1]
    u = ref.rng.random(len(obs))
    by_row = [act_row(o, c.weights, c.biases, c.mean, c.scale, ui) for o, ui in zip(obs, u)]
    np.testing.assert_array_equal(large, by_row)
