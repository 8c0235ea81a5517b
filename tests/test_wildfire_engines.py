"""The fast wildfire engine against the SimPy reference, and the SimPy ordering FS relies on."""

from __future__ import annotations

import numpy as np
import pytest
import simpy
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from repro.core.rollout import DecisionBatch, Rollout, children
from repro.envs.wildfire import WildfireConfig, draw_episodes, make_env, make_reference_env
from repro.envs.wildfire.params import SAME_INSTANT_ORDERS, EpisodeStream
from repro.envs.wildfire.policies import POLICIES

DTS = (None, 10 ** -1, 10 ** -0.5, 1.0, 10 ** 0.5, 10.0)
MAX_DECISIONS = 4096


class Scripted:
    """Actions and policy uniforms that depend on (episode, agent, index) only, so two engines
    asking in different groupings get the same answers."""

    def __init__(self, seed: int, n_episodes: int, n_agents: int, n_actions: int):
        rng = np.random.default_rng(seed)
        self.actions = rng.integers(0, n_actions, size=(n_episodes, n_agents, MAX_DECISIONS))
        self.u = rng.random((n_episodes, n_agents, MAX_DECISIONS, 2))

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        return self.actions[batch.episode, batch.agent, batch.index % MAX_DECISIONS]

    def uniforms(self, batch: DecisionBatch) -> np.ndarray:
        return self.u[batch.episode, batch.agent, batch.index % MAX_DECISIONS]


def make_policy(kind: str, seed: int, cfg: WildfireConfig, n_episodes: int):
    s = Scripted(seed, n_episodes, cfg.n_agents, cfg.n_actions)
    return s if kind == "scripted" else POLICIES[kind](uniforms=s.uniforms)


def assert_same(ref: Rollout, fast: Rollout) -> None:
    assert ref.n_decisions == fast.n_decisions
    np.testing.assert_array_equal(ref.path_start, fast.path_start)
    np.testing.assert_array_equal(ref.path_episode, fast.path_episode)
    np.testing.assert_array_equal(ref.path_agent, fast.path_agent)
    np.testing.assert_array_equal(ref.actions, fast.actions)
    np.testing.assert_allclose(ref.info["decision_time"], fast.info["decision_time"], rtol=0,
                               atol=1e-9)
    np.testing.assert_allclose(ref.info["end_time"], fast.info["end_time"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(ref.durations, fast.durations, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ref.obs, fast.obs, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ref.rewards, fast.rewards, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ref.episode_return, fast.episode_return, rtol=0, atol=1e-12)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2 ** 32 - 1), dt=st.sampled_from(DTS),
       t_health=st.sampled_from((3.0, 2.9999)), q1=st.booleans(), q2=st.booleans(),
       q3=st.booleans(), q4=st.booleans(), q5=st.booleans(), q6=st.booleans(),
       order=st.sampled_from(SAME_INSTANT_ORDERS), round_neg=st.booleans(),
       cut_goes_on=st.booleans(), ranking_resolution=st.sampled_from((1e-9, 0.0)),
       kind=st.sampled_from(("scripted", "random", "nearest", "flowchart")),
       max_decisions=st.sampled_from((None, None, 1, 3, 12)),
       gamma=st.sampled_from((0.02, 0.02, 0.05)))  # gamma also sets the episode cap T_max
def test_engines_agree_decision_by_decision(seed, dt, t_health, q1, q2, q3, q4, q5, q6, order,
                                            round_neg, cut_goes_on, ranking_resolution, kind,
                                            max_decisions, gamma):
    cfg = WildfireConfig(dt=dt, t_health=t_health, quirk_q1_stale_attack=q1,
                         quirk_q2_penalty_party_only=q2, quirk_q3_unclamped_health=q3,
                         quirk_q4_latency_not_interrupted=q4,
                         quirk_q5_discount_from_action_start=q5, quirk_q6_short_flight_stays=q6,
                         same_instant_order=order,
                         fs_round_negative_delays=round_neg, cut_flight_continues=cut_goes_on,
                         ranking_resolution=ranking_resolution, max_decisions=max_decisions,
                         gamma=gamma)
    n = 2
    ref = make_reference_env(cfg).rollout(make_policy(kind, seed, cfg, n), n, seed)
    fast = make_env(cfg).rollout(make_policy(kind, seed, cfg, n), n, seed)
    assert_same(ref, fast)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2 ** 32 - 1), dt=st.sampled_from(DTS + (1e-3,)),
       t_health=st.sampled_from((3.0, 2.9999)),
       # (N, clusters): each pair compiles the kernels anew (the state record's shape)
       layout=st.sampled_from(((3, 3), (2, 1), (6, 6))), fire_out_first=st.booleans(),
       q3=st.booleans(),
       q4=st.booleans(), q5=st.booleans(),
       kind=st.sampled_from(("scripted", "random", "nearest", "flowchart")))
def test_engines_agree_on_other_layouts_orders_and_races(seed, dt, t_health, layout,
                                                         fire_out_first, q3, q4, q5, kind):
    """The switches of the beyond-the-paper studies, n_clusters and fire_out_first (X2, X4), and
    the race count, which both engines keep apart (ED never races); counting changes nothing."""
    n_agents, n_clusters = layout
    cfg = WildfireConfig(dt=dt, t_health=t_health, n_clusters=n_clusters, n_agents=n_agents,
                         n_observed=min(5, 3 * n_clusters), fire_out_first=fire_out_first,
                         quirk_q3_unclamped_health=q3, quirk_q4_latency_not_interrupted=q4,
                         quirk_q5_discount_from_action_start=q5)

    def policy():
        s = Scripted(seed, 2, n_agents, cfg.n_actions)
        return s if kind == "scripted" else POLICIES[kind](uniforms=s.uniforms,
                                                            n_observed=cfg.n_observed)

    ref = make_reference_env(cfg, count_races=True).rollout(policy(), 2, seed)
    fast = make_env(cfg, count_races=True).rollout(policy(), 2, seed)
    assert_same(ref, fast)
    np.testing.assert_array_equal(ref.info["races"], fast.info["races"])
    if dt is None:
        assert not fast.info["races"].any()
    uncounted = make_env(cfg).rollout(policy(), 2, seed)
    assert "races" not in uncounted.info
    np.testing.assert_array_equal(uncounted.obs, fast.obs)


def test_engines_agree_on_a_larger_batch():
    """Many episodes in one fast batch (rounds mix episodes at different stages)."""
    cfg = WildfireConfig(dt=10 ** 0.5, quirk_q2_penalty_party_only=False)
    n = 12
    ref = make_reference_env(cfg).rollout(make_policy("flowchart", 7, cfg, n), n, 11)
    fast = make_env(cfg).rollout(make_policy("flowchart", 7, cfg, n), n, 11)
    assert_same(ref, fast)
    assert ref.rewards.max() > 0


def test_engines_agree_with_many_uavs():
    """Beyond the 128 pending events the engine's heap once had (60 UAVs overfilled it, 140
    overran it): the heap is sized from the number of UAVs. (One size: each compiles the engine
    for its state layout.)"""
    cfg = WildfireConfig(n_agents=140, dt=1.0)
    ref = make_reference_env(cfg).rollout(make_policy("random", 3, cfg, 1), 1, 5)
    fast = make_env(cfg).rollout(make_policy("random", 3, cfg, 1), 1, 5)
    assert_same(ref, fast)


class FlyToClosest:
    """Always action 0: once at a fire, every flight is to that fire, takes no time, and the UAV
    decides again after the latency (the regime long ED training drifts into)."""

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        return np.zeros(len(batch), np.int64)


@pytest.mark.parametrize("dt", [None, 1.0])
def test_decision_limit_ends_the_episode(dt):
    """With max_decisions, an episode ends when a UAV's macro-action ends after its last allowed
    decision; both engines agree; paths chain up to the end time as at T_max."""
    cfg = WildfireConfig(dt=dt, max_decisions=200)
    ref = make_reference_env(cfg).rollout(FlyToClosest(), 3, 5)
    fast = make_env(cfg).rollout(FlyToClosest(), 3, 5)
    assert_same(ref, fast)
    lengths = np.diff(fast.path_start).reshape(3, cfg.n_agents)
    assert np.all(lengths.max(axis=1) == 200)  # each episode ended by a UAV at its limit
    if dt is None:  # zero-length flights last one latency (FS rounds them up to the grid)
        assert np.sum(fast.durations < 2 * cfg.decision_latency) > 150
    assert np.all(fast.info["end_time"] < cfg.t_max)
    for p in range(fast.n_paths):
        sl = slice(fast.path_start[p], fast.path_start[p + 1])
        t = fast.info["decision_time"][sl]
        np.testing.assert_allclose(t[-1] + fast.durations[sl][-1],
                                   fast.info["end_time"][fast.path_episode[p]], atol=1e-9)


def test_stay_flight_loops_are_bounded_by_default():
    """A UAV that flies to the fire it is at makes 100,000 decisions in about a second of
    simulated time, and without a limit only T_max ends its loop; the default limit ends such an
    episode at 1,000 decisions, reported truncated, while the nearest-fire heuristic's episodes
    end by themselves."""
    cfg = WildfireConfig(max_decisions=100_000)
    limited = make_env(cfg).rollout(FlyToClosest(), 1, 5)
    assert np.diff(limited.path_start).max() == 100_000
    first_arrival = limited.info["decision_time"][1:][limited.durations[:-1] > 1e-3].max()
    assert limited.info["end_time"][0] - first_arrival < 100_000 * 1.01 * cfg.decision_latency
    env = make_env(WildfireConfig())
    looping = env.rollout(FlyToClosest(), 4, 5)
    assert np.diff(looping.path_start).max() == 1000 and looping.truncated.all()
    nearest = env.rollout(POLICIES["nearest"](np.random.default_rng(0)), 50, 5)
    assert nearest.n_truncated == 0 and nearest.truncated.shape == (50,)


def test_rollout_structure():
    cfg = WildfireConfig()
    r = make_env(cfg).rollout(make_policy("flowchart", 3, cfg, 5), 5, 3)
    assert r.n_paths == 5 * cfg.n_agents
    assert r.obs.shape == (r.n_decisions, 28)
    for p in range(r.n_paths):
        sl = slice(r.path_start[p], r.path_start[p + 1])
        t = r.info["decision_time"][sl]
        assert t[0] == 0.0 and np.all(np.diff(t) >= 0)
        # durations chain the decisions and end at the episode's end
        np.testing.assert_allclose(t[1:], t[:-1] + r.durations[sl][:-1], atol=1e-9)
        np.testing.assert_allclose(t[-1] + r.durations[sl][-1],
                                   r.info["end_time"][r.path_episode[p]], atol=1e-9)
        np.testing.assert_allclose(r.obs[sl][1:, -1], r.durations[sl][:-1], atol=1e-12)
    assert np.all(r.info["end_time"] <= cfg.t_max + 1e-9)


@pytest.mark.parametrize("answer", [
    lambda n: np.full(n, 6), lambda n: np.full(n, -1), lambda n: np.zeros(n + 1, np.int64),
    lambda n: np.zeros(n), lambda n: np.r_[np.zeros(n - 1, np.int64), 6]])
def test_both_engines_reject_bad_actions(answer):
    """Out of range (the fast engine checks the range in its kernel), wrong length, not integers."""
    cfg = WildfireConfig()
    for env in (make_env(cfg), make_reference_env(cfg)):
        with pytest.raises(ValueError, match="integer actions in"):
            env.rollout(lambda batch: answer(len(batch)), 4, 0)


def test_draws_are_deterministic_per_seed():
    cfg = WildfireConfig()
    d = draw_episodes(cfg, 3, 5)
    again = draw_episodes(cfg, 3, 5)
    np.testing.assert_array_equal(d.starts, again.starts)
    assert d.starts.shape == (3, cfg.n_agents, 2) and np.all(np.abs(d.starts) <= 1)
    assert d.holds.shape == (3, cfg.n_agents, cfg.hold_table)
    assert abs(d.holds.mean() - cfg.hold_mean) < 0.05
    assert not np.array_equal(d.starts[0], d.starts[1])


def test_draws_take_a_seed_sequence_without_advancing_it():
    cfg = WildfireConfig()
    ss = np.random.SeedSequence(7)
    first, second = draw_episodes(cfg, 3, ss), draw_episodes(cfg, 3, ss)
    np.testing.assert_array_equal(first.starts, second.starts)
    np.testing.assert_array_equal(first.starts, draw_episodes(cfg, 3, 7).starts)


def test_hold_table_outlasts_t_max():
    """A UAV that only holds never reuses a duration: the table grows when T_max does."""
    assert WildfireConfig().hold_table == 128  # the paper's settings: the draws as always
    cfg = WildfireConfig(gamma=0.005)  # T_max 1060 s
    holds = draw_episodes(cfg, 1, 0).holds[0]
    assert holds.shape[1] == cfg.hold_table > cfg.t_max / (cfg.hold_mean - 3 * cfg.hold_std)
    assert holds.sum(axis=1).min() > cfg.t_max  # every UAV's table lasts past T_max


def test_draws_are_prefix_stable():
    """Episode e's start positions and holds do not depend on the batch size; seeds differ."""
    cfg = WildfireConfig()
    small, large = draw_episodes(cfg, 3, 9), draw_episodes(cfg, 50, 9)
    np.testing.assert_array_equal(small.starts, large.starts[:3])
    np.testing.assert_array_equal(small.holds, large.holds[:3])
    other = draw_episodes(cfg, 3, 10)
    assert not np.array_equal(small.starts, other.starts)
    assert not np.array_equal(small.holds, other.holds)


@pytest.mark.parametrize("seed", [0, 1])
def test_holds_are_numpys_normal_draws(seed):
    """The holds are numpy's ``Generator.normal`` values, and the stream is where that call would
    leave it: the same bits, the ziggurat's tail (beyond 3.44 standard deviations) included."""
    cfg = WildfireConfig()
    stream = EpisodeStream(cfg, seed)
    numpy_stream = np.random.default_rng(children(seed, 2)[1])
    first = stream.draw(700).holds
    assert first.tobytes() == numpy_stream.normal(cfg.hold_mean, cfg.hold_std,
                                                  first.shape).tobytes()
    assert np.sum(np.abs(first - cfg.hold_mean) > 3.45 * cfg.hold_std) > 50  # the tail drawn
    second = stream.draw(2).holds  # where the first batch left the stream
    assert second.tobytes() == numpy_stream.normal(cfg.hold_mean, cfg.hold_std,
                                                   second.shape).tobytes()
    assert stream._holds.bit_generator.state == numpy_stream.bit_generator.state


def test_simpy_same_instant_order():
    """What FS semantics rely on: events due at the same instant are processed in the order they
    were scheduled (first scheduled, first processed), whatever their delays and whenever they
    were scheduled."""
    env = simpy.Environment()
    order: list[str] = []

    def waiter(name, start, delay):
        yield env.timeout(start)
        yield env.timeout(delay)  # due at start + delay = 4 for everyone
        order.append(name)

    for name, start in (("c", 3.0), ("b", 2.0), ("a", 0.0), ("d", 1.0), ("e", 4.0)):
        env.process(waiter(name, start, 4.0 - start))
    env.run()
    # scheduled at t = 0 (a), 1 (d), 2 (b), 3 (c), 4 (e)
    assert order == ["a", "d", "b", "c", "e"]


def test_simpy_interrupt_precedes_timeouts_at_same_instant():
    """An interrupt (URGENT) issued at t is processed before NORMAL timeouts already due at t."""
    env = simpy.Environment()
    order: list[str] = []

    def interrupter():
        yield env.timeout(5.0)  # scheduled first
        order.append("interrupter")
        target_proc.interrupt()

    def target():
        try:
            yield env.timeout(5.0)  # scheduled second
            order.append("target done")
        except simpy.Interrupt:
            order.append("target interrupted")

    def sleeper():
        yield env.timeout(5.0)  # scheduled third
        order.append("sleeper")

    env.process(interrupter())
    target_proc = env.process(target())
    env.process(sleeper())
    env.run()
    assert order == ["interrupter", "target interrupted", "sleeper"]


def _sampler(cfg: WildfireConfig, seed: int, n_actions: int | None = None):
    import torch

    from repro.learn.policy import CategoricalPolicy, ObsNormalizer, Sampler

    torch.manual_seed(seed)
    policy = CategoricalPolicy(cfg.obs_dim, n_actions or cfg.n_actions, (32, 32))
    with torch.no_grad():
        policy.net[-1].weight.mul_(30.0)  # far from uniform: actions depend on observations
    return Sampler(policy, ObsNormalizer(cfg.obs_dim), np.random.default_rng(seed))


def test_a_sampler_with_other_actions_is_rejected():
    """A network with more outputs than actions meets the range check."""
    cfg = WildfireConfig()
    with pytest.raises(ValueError, match="integer actions in"):
        make_env(cfg).rollout(_sampler(cfg, 0, n_actions=cfg.n_actions + 3), 2, 0)
