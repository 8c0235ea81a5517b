"""The policy evaluated row by row in compiled code (repro.learn.policy_kernel) against numpy, torch
and the sampler."""

from __future__ import annotations

import copy

import numpy as np
import torch
from numba import njit

from repro.core.rollout import DecisionBatch
from repro.learn.policy import CategoricalPolicy, ObsNormalizer, Sampler
from repro.learn.policy_kernel import (LAYER_SLOTS, act_row, depth, logits_row, sigmoid64, slots,
                                      tanh32, tanh64)


@njit  # not cached: numba's cache would not see a change of tanh32's file
def _tanh_all(v, out):
    for i in range(len(v)):
        out[i] = tanh32(v[i])


@njit  # not cached, as _tanh_all
def _depth(layers):
    return depth(layers)


def test_slots_pad_a_network_to_whole_slots_and_depth_counts_its_layers():
    """Networks of one to four layers share one tuple type (so one compilation of each kernel); a
    deeper one takes the next multiple; the empty slots are not layers."""
    w = np.ones((3, 2), np.float32)
    for layers in (1, 2, 4, 5):
        padded = slots([w] * layers, layers, np.float32, 2)
        assert len(padded) == (LAYER_SLOTS if layers <= LAYER_SLOTS else 2 * LAYER_SLOTS)
        assert all(a.shape == (0, 0) and a.dtype == np.float32 for a in padded[layers:])
        assert _depth(padded) == layers
    hidden = slots([], 1, np.float64, 2)  # a network without hidden layers
    assert len(hidden) == LAYER_SLOTS and _depth(hidden) == 0


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


@njit  # not cached, as _tanh_all
def _float64_all(v, tanh_out, sigmoid_out):
    for i in range(len(v)):
        tanh_out[i] = tanh64(v[i])
        sigmoid_out[i] = sigmoid64(v[i])


def _ulps(got: np.ndarray, exact: np.ndarray) -> np.ndarray:
    """|got - exact| in units in the last place of the float64 nearest ``exact`` (80-bit)."""
    return np.abs((got.astype(np.longdouble) - exact)
                  / np.spacing(np.abs(exact.astype(np.float64))).astype(np.longdouble))


def test_tanh64_and_sigmoid64_are_within_2_5_ulps_of_the_80_bit_functions():
    """The float64 functions of the gru policy against numpy's 80-bit long double tanh and exp
    (x86's extended precision, 11 more bits), over the range that matters and beyond."""
    rng = np.random.default_rng(1)
    v = np.concatenate([
        np.linspace(-45.0, 45.0, 1_000_001),
        rng.standard_normal(1_000_000) * 3.0,
        10.0 ** rng.uniform(-300.0, 1.0, 500_000) * rng.choice([-1.0, 1.0], 500_000),
        rng.uniform(-750.0, 750.0, 100_000),
        [0.0, -0.0, 20.0, -20.0, 708.0, -708.0, 1e-320],
    ])
    th, sg = np.empty_like(v), np.empty_like(v)
    _float64_all(v, th, sg)
    wide = v.astype(np.longdouble)
    assert _ulps(th, np.tanh(wide)).max() <= 2.5
    sigmoid = 1.0 / (1.0 + np.exp(-wide))
    normal = v >= -708.0  # below, e^v is about the smallest normal number: the function gives 0
    assert _ulps(sg[normal], sigmoid[normal]).max() <= 2.5
    assert (sg[~normal] == 0.0).all() and (sigmoid[~normal] < 4e-308).all()
    assert np.array_equal(np.signbit(th), np.signbit(v))  # -0 stays -0
    special = np.array([np.nan, np.inf, -np.inf, 1e308, -1e308])
    th, sg = np.empty_like(special), np.empty_like(special)
    _float64_all(special, th, sg)
    np.testing.assert_array_equal(th, [np.nan, 1.0, -1.0, 1.0, -1.0])
    np.testing.assert_array_equal(sg, [np.nan, 1.0, 0.0, 1.0, 0.0])


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
