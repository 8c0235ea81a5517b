"""M-GAE against an independent GAE (stable-baselines3) and against hand-computed cases."""

from __future__ import annotations

import numpy as np
import pytest

from repro.learn import m_gae
from repro.learn.m_gae import m_gae_paths


def sb3_gae(rewards, values, last_value, done, gamma_d, lambda_d):
    """stable-baselines3's GAE on one trajectory (n_envs = 1)."""
    gym = pytest.importorskip("gymnasium")
    from stable_baselines3.common.buffers import RolloutBuffer

    n = len(rewards)
    buf = RolloutBuffer(n, gym.spaces.Box(-1, 1, (1,)), gym.spaces.Discrete(2), device="cpu",
                        gamma=gamma_d, gae_lambda=lambda_d, n_envs=1)
    buf.rewards[:, 0] = rewards
    buf.values[:, 0] = values
    buf.episode_starts[:, 0] = 0.0
    buf.episode_starts[0, 0] = 1.0
    import torch

    buf.compute_returns_and_advantage(torch.tensor([last_value]), np.array([done]))
    return buf.advantages[:, 0].astype(float), buf.returns[:, 0].astype(float)


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("done", [True, False])
def test_unit_durations_equal_standard_gae(seed, done):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 40))
    rewards, values = rng.normal(size=n), rng.normal(size=n)
    last = 0.0 if done else float(rng.normal())
    gamma, lam = rng.uniform(0.01, 0.5), rng.uniform(0.5, 2.0)
    adv, ret = m_gae(rewards, np.ones(n), values, last, gamma, lam)
    # M-GAE's per-step factor exp(-gamma lam) is GAE's gamma_d * lambda_d with gamma_d = exp(-gamma)
    sb_adv, sb_ret = sb3_gae(rewards, values, last, done, np.exp(-gamma),
                             np.exp(-gamma * (lam - 1)))
    np.testing.assert_allclose(adv, sb_adv, rtol=1e-5, atol=1e-5)  # sb3 stores float32
    # sb3's returns are A + V (TD(lambda)); with lam = 1 they are the discounted returns
    adv1, ret1 = m_gae(rewards, np.ones(n), values, last, gamma, 1.0)
    _, sb_ret1 = sb3_gae(rewards, values, last, done, np.exp(-gamma), 1.0)
    np.testing.assert_allclose(ret1, sb_ret1, rtol=1e-5, atol=1e-5)


def test_hand_computed_unequal_durations():
    gamma, lam = 0.1, 0.5
    r = np.array([1.0, 2.0, -1.0])
    dt = np.array([2.0, 0.5, 3.0])
    v = np.array([0.5, -0.2, 0.3])
    last = 0.7
    d0 = 1.0 + np.exp(-0.2) * -0.2 - 0.5
    d1 = 2.0 + np.exp(-0.05) * 0.3 + 0.2
    d2 = -1.0 + np.exp(-0.3) * 0.7 - 0.3
    a2 = d2
    a1 = d1 + np.exp(-0.025) * a2
    a0 = d0 + np.exp(-0.1) * a1
    g2 = -1.0 + np.exp(-0.3) * last
    g1 = 2.0 + np.exp(-0.05) * g2
    g0 = 1.0 + np.exp(-0.2) * g1
    adv, ret = m_gae(r, dt, v, last, gamma, lam)
    np.testing.assert_allclose(adv, [a0, a1, a2], rtol=1e-12)
    np.testing.assert_allclose(ret, [g0, g1, g2], rtol=1e-12)


def test_lambda_extremes_and_durations():
    """lam enters as an exponent: lam = 0 sums the deltas undiscounted, a huge lam keeps only the
    one-step delta (the opposite ends from GAE's lambda_d = 0 and 1)."""
    r, dt, v = np.array([1.0, 1.0]), np.array([1.0, 10.0]), np.array([2.0, 3.0])
    deltas = [1 + np.exp(-0.05) * 3 - 2, 1 - 3]
    adv, _ = m_gae(r, dt, v, 0.0, 0.05, 0.0)
    np.testing.assert_allclose(adv, [deltas[0] + deltas[1], deltas[1]])
    adv, _ = m_gae(r, dt, v, 0.0, 0.05, 1e6)
    np.testing.assert_allclose(adv, deltas)
    # stretching the first action discounts everything after it more
    _, ret_short = m_gae(r, np.array([1.0, 1.0]), v, 0.0, 0.05, 1.0)
    _, ret_long = m_gae(r, np.array([5.0, 1.0]), v, 0.0, 0.05, 1.0)
    assert ret_long[0] < ret_short[0] and ret_long[1] == ret_short[1]


@pytest.mark.parametrize("seed", range(3))
def test_batched_equals_per_path(seed):
    rng = np.random.default_rng(seed)
    lengths = rng.integers(0, 30, size=25)
    start = np.concatenate([[0], np.cumsum(lengths)])
    d = int(start[-1])
    r, dt, v = rng.normal(size=d), rng.exponential(2.0, size=d), rng.normal(size=d)
    last = rng.normal(size=len(lengths))
    gamma, lam = 0.02, 1.7
    adv, ret = m_gae_paths(r, dt, v, start, gamma, lam, last)
    for p in range(len(lengths)):
        s = slice(start[p], start[p + 1])
        a, g = m_gae(r[s], dt[s], v[s], last[p], gamma, lam)
        np.testing.assert_allclose(adv[s], a, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(ret[s], g, rtol=1e-10, atol=1e-12)
    # default: every path ends with its episode (V = 0 afterwards)
    adv0, _ = m_gae_paths(r, dt, v, start, gamma, lam)
    s = slice(start[1], start[2])
    np.testing.assert_allclose(adv0[s], m_gae(r[s], dt[s], v[s], 0.0, gamma, lam)[0], rtol=1e-10)


def test_returns_match_rollout_discounted_path_returns():
    from repro.core.rollout import discounted_path_returns

    rng = np.random.default_rng(7)
    start = np.array([0, 4, 4, 9])
    r, dt = rng.normal(size=9), rng.exponential(size=9)
    _, ret = m_gae_paths(r, dt, np.zeros(9), start, 0.3, 1.0)
    np.testing.assert_allclose(ret[[0, 4]], discounted_path_returns(r, dt, start, 0.3)[[0, 2]])


def test_step_index_numbers_the_decisions_of_each_path_from_0():
    from repro.core.rollout import Rollout

    start = np.array([0, 3, 3, 4, 8])  # paths of 3, 0, 1 and 4 decisions
    ro = Rollout(obs=np.zeros((8, 1)), actions=np.zeros(8, np.int64), rewards=np.zeros(8),
                 durations=np.ones(8), path_start=start, path_episode=np.zeros(4, np.int64),
                 path_agent=np.arange(4), episode_return=np.zeros(1))
    assert ro.step_index().tolist() == [0, 1, 2, 0, 0, 1, 2, 3]
