"""M-GAE against an independent GAE (stable-baselines3) and against hand-computed cases."""

from __future__ import annotations

import numpy as np
import pytest

from repro.learn import m_gae
from repro.learn.m_gae import ESTIMATORS, advantage_paths, m_gae_paths


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


def direct_sums(estimator, r, dt, v, last, gamma, lam, m):
    """The alternatives of X1 on one path as sums over its decisions (docs/semantics.md section
    5.3), m the batch's mean duration: A_k = sum_l w_kl delta_{k+l}, R_k = sum_l d_kl r_{k+l} +
    d_kn V_n, with d_kl the discount from decision k to k + l and w_kl the trace."""
    n = len(r)
    t = np.concatenate([[0.0], np.cumsum(dt)])
    vv = np.append(v, last)
    if estimator == "decision-gae":  # one step per decision
        steps = np.arange(n + 1, dtype=float)
        discount = np.exp(-gamma * m * (steps[None, :] - steps[:, None]))
        trace = np.exp(-gamma * lam * m * (steps[None, :] - steps[:, None]))
    else:  # duration-gae: continuous-time discount, lambda_d per decision
        lambda_d = np.exp(-gamma * (lam - 1) * m)
        discount = np.exp(-gamma * (t[None, :] - t[:, None]))
        steps = np.arange(n + 1)
        trace = discount * lambda_d ** (steps[None, :] - steps[:, None]).astype(float)
    deltas = r + np.array([discount[k, k + 1] for k in range(n)]) * vv[1:] - vv[:-1]
    adv = np.array([sum(trace[k, j] * deltas[j] for j in range(k, n)) for k in range(n)])
    ret = np.array([sum(discount[k, j] * r[j] for j in range(k, n)) + discount[k, n] * last
                    for k in range(n)])
    return adv, ret


@pytest.mark.parametrize("estimator", ["decision-gae", "duration-gae"])
@pytest.mark.parametrize("seed", range(3))
def test_alternative_estimators_equal_their_sum_forms(estimator, seed):
    """Each alternative of claim X1 against its direct sum, on the paths of one batch: m is the
    mean duration over the whole batch, not over a path."""
    rng = np.random.default_rng(seed)
    lengths = np.array([5, 0, 1, 7])
    start = np.concatenate([[0], np.cumsum(lengths)])
    d = int(start[-1])
    r, dt, v = rng.normal(size=d), rng.exponential(3.0, size=d), rng.normal(size=d)
    last = rng.normal(size=len(lengths))
    gamma, lam, m = 0.05, rng.uniform(0.5, 3.0), dt.mean()
    adv, ret = advantage_paths(estimator, r, dt, v, start, gamma, lam, last)
    for p in range(len(lengths)):
        s = slice(start[p], start[p + 1])
        a, g = direct_sums(estimator, r[s], dt[s], v[s], last[p], gamma, lam, m)
        np.testing.assert_allclose(adv[s], a, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(ret[s], g, rtol=1e-10, atol=1e-12)


def test_the_estimators_agree_where_they_should():
    """With every duration equal, all three are M-GAE; at lam = 1 duration-gae is M-GAE bit for
    bit (lambda_d = 1); with unequal durations they differ."""
    rng = np.random.default_rng(4)
    start = np.array([0, 6, 10])
    r, v = rng.normal(size=10), rng.normal(size=10)
    even, uneven = np.full(10, 2.5), rng.exponential(2.5, size=10)
    results = {(e, k): advantage_paths(e, r, dt, v, start, 0.1, 1.7)
               for e in ESTIMATORS for k, dt in (("even", even), ("uneven", uneven))}
    for e in ESTIMATORS:
        for a, b in zip(results[e, "even"], results["m-gae", "even"]):
            np.testing.assert_allclose(a, b, rtol=1e-12)
        if e != "m-gae":
            assert not np.allclose(results[e, "uneven"][0], results["m-gae", "uneven"][0])
    one = [advantage_paths(e, r, uneven, v, start, 0.1, 1.0) for e in ("m-gae", "duration-gae")]
    assert all(np.array_equal(a, b) for a, b in zip(*one))


def test_step_index_numbers_the_decisions_of_each_path_from_0():
    from repro.core.rollout import Rollout

    start = np.array([0, 3, 3, 4, 8])  # paths of 3, 0, 1 and 4 decisions
    ro = Rollout(obs=np.zeros((8, 1)), actions=np.zeros(8, np.int64), rewards=np.zeros(8),
                 durations=np.ones(8), path_start=start, path_episode=np.zeros(4, np.int64),
                 path_agent=np.arange(4), episode_return=np.zeros(1))
    assert ro.step_index().tolist() == [0, 1, 2, 0, 0, 1, 2, 3]
