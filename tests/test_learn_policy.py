"""The shared policy's sampler and the observation normaliser."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from repro.core.rollout import DecisionBatch
from repro.learn.policy import CategoricalPolicy, ObsNormalizer, Sampler


def batch(obs: np.ndarray) -> DecisionBatch:
    m = len(obs)
    return DecisionBatch(obs=obs, episode=np.arange(m), agent=np.zeros(m, np.int64),
                         index=np.zeros(m, np.int64))


def test_normalizer_equals_moments_of_everything_seen():
    rng = np.random.default_rng(0)
    chunks = [rng.normal(3.0, 5.0, size=(n, 4)) * [1, 1e4, 1e-2, 0] for n in (7, 100, 1, 30)]
    norm = ObsNormalizer(4)
    for c in chunks:
        norm.update(c)
    every = np.concatenate(chunks)
    np.testing.assert_allclose(norm.mean, every.mean(axis=0), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(norm.var, every.var(axis=0), rtol=1e-10, atol=1e-12)
    z = norm(every)
    np.testing.assert_allclose(z[:, :3].std(axis=0), 1.0, rtol=1e-5)
    assert np.all(z[:, 3] == 0.0)  # a constant feature maps to 0


def test_normalizer_passes_give_numpys_bits():
    """The compiled moments and standardisation are numpy's expressions bit for bit (the committed
    training results were made with those); 30,000 rows, so a summation in another order would
    show."""
    x = np.random.default_rng(1).normal(100.0, 7.0, size=(30_000, 5))
    norm = ObsNormalizer(5)
    norm.update(x)
    np.testing.assert_array_equal(norm.mean, x.mean(axis=0))
    np.testing.assert_array_equal(norm.var, x.var(axis=0))
    np.testing.assert_array_equal(norm(x), (x - norm.mean) / np.sqrt(norm.var + norm.eps))


def test_sampler_matches_network_and_its_probabilities():
    torch.manual_seed(0)
    policy = CategoricalPolicy(3, 4, (16, 16))
    with torch.no_grad():
        policy.net[-1].weight.mul_(50.0)  # a clearly non-uniform policy
    norm = ObsNormalizer(3)
    norm.update(np.random.default_rng(1).normal(size=(20, 3)) * 10)
    obs = np.array([[1.0, -2.0, 5.0]])
    sampler = Sampler(policy, norm, np.random.default_rng(2))
    with torch.no_grad():
        expected = policy(torch.as_tensor(norm(obs), dtype=torch.float32)).exp().double().numpy()
    np.testing.assert_allclose(sampler.probabilities(obs), expected, atol=1e-6)
    n = 40_000
    actions = sampler(batch(np.repeat(obs, n, axis=0)))
    freq = np.bincount(actions, minlength=4) / n
    assert np.all(np.abs(freq - expected[0])
                  < 4 * np.sqrt(expected[0] * (1 - expected[0]) / n) + 1e-9)
    # the generator alone decides the draws
    again = Sampler(policy, norm, np.random.default_rng(2))(batch(np.repeat(obs, n, axis=0)))
    np.testing.assert_array_equal(actions, again)


def test_linear_baseline_recovers_linear_features_and_mlp_fits():
    from repro.learn.baseline import LinearFeatureBaseline, MLPBaseline

    rng = np.random.default_rng(0)
    obs, index = rng.normal(size=(500, 3)), rng.integers(0, 50, 500)
    feats = LinearFeatureBaseline.features(obs, index)
    truth = rng.normal(size=feats.shape[1])
    lin = LinearFeatureBaseline(3)
    assert np.all(lin.predict(obs, index) == 0.0)
    assert lin.fit(obs, index, feats @ truth) < 1e-10
    new_obs, new_index = rng.normal(size=(50, 3)), rng.integers(0, 50, 50)
    expected = LinearFeatureBaseline.features(new_obs, new_index) @ truth
    np.testing.assert_allclose(lin.predict(new_obs, new_index), expected, rtol=1e-4, atol=1e-4)
    torch.manual_seed(0)
    net = MLPBaseline(3, (16,), iters=50)
    assert np.all(net.predict(obs, index) == 0.0)
    target = 1e4 + 3e3 * np.sin(obs[:, 0])  # bus-like scale
    assert net.fit(obs, index, target) < 0.05


def test_inverse_cdf_sampling_by_hand():
    from repro.learn.policy_kernel import sample_row

    # probabilities 1/4, 1/4, 1/2: the CDF's steps are at u = 0.25 and 0.5
    logits = np.log(np.array([1.0, 1.0, 2.0], np.float32))
    u = [0.0, 0.2499, 0.25, 0.4999, 0.9999999]
    actions = [sample_row(logits, ui, np.empty(3)) for ui in u]
    assert actions == [0, 0, 1, 1, 2]


def test_sampler_calls_of_different_sizes_do_not_interfere():
    torch.manual_seed(0)
    sampler = Sampler(CategoricalPolicy(3, 4, (8,)), ObsNormalizer(3), np.random.default_rng(0))
    rng = np.random.default_rng(1)
    big, small = rng.normal(size=(300, 3)), rng.normal(size=(2, 3))
    first = sampler.probabilities(small)
    sampler.probabilities(big)
    np.testing.assert_array_equal(sampler.probabilities(small), first)


def test_linear_baseline_features_are_rllabs():
    from repro.learn.baseline import LinearFeatureBaseline

    rng = np.random.default_rng(0)
    obs, index = rng.normal(size=(200, 5)) * 20, rng.integers(0, 300, 200)  # some clipped
    obs[0, 0] = np.nan  # passed through, as np.clip does
    z, k = np.clip(obs, -10, 10), (index / 100.0)[:, None]
    expected = np.concatenate([z, z**2, k, k**2, k**3, np.ones_like(k)], axis=1)
    np.testing.assert_array_equal(LinearFeatureBaseline.features(obs, index), expected)
    assert np.isnan(expected[0, 0])


def test_linear_baseline_solves_as_numpys_lstsq_did():
    """The regression's matrix products and solve are torch's (numpy's BLAS stays out of the
    learner): the coefficients are those of rllab's numpy formulation to rounding."""
    from repro.learn.baseline import LinearFeatureBaseline

    rng = np.random.default_rng(3)
    obs, index = rng.normal(size=(5000, 6)) * 3, rng.integers(0, 400, 5000)
    returns = obs[:, 0] ** 2 - index / 50 + rng.normal(size=5000)
    lin = LinearFeatureBaseline(6)
    error = lin.fit(obs, index, returns)
    x = LinearFeatureBaseline.features(obs, index)
    gram = x.T @ x + 1e-5 * np.eye(x.shape[1])
    expected = np.linalg.lstsq(gram, x.T @ returns, rcond=None)[0]
    np.testing.assert_allclose(lin.coeffs, expected, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(lin.predict(obs, index), x @ expected, rtol=1e-9, atol=1e-9)
    assert error == pytest.approx(np.mean((x @ expected - returns) ** 2) / returns.var())


def test_linear_baseline_with_a_nan_has_nan_coefficients():
    """A NaN observation gives NaN coefficients (LAPACK would refuse the system, or hang)."""
    from repro.learn.baseline import LinearFeatureBaseline

    rng = np.random.default_rng(4)
    obs, index = rng.normal(size=(100, 2)), np.arange(100)
    obs[7, 1] = np.nan
    lin = LinearFeatureBaseline(2)
    assert np.isnan(lin.fit(obs, index, rng.normal(size=100)))
    assert np.all(np.isnan(lin.coeffs))
