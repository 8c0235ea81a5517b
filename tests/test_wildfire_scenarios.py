"""Scripted episodes that pin down the mechanisms of docs/semantics.md section 3, in both
engines."""

from __future__ import annotations

import numpy as np
import pytest

from repro.core.rollout import DecisionBatch
from repro.envs.wildfire import (EpisodeDraws, WildfireConfig, fire_positions, make_env,
                                 make_reference_env)
from repro.envs.wildfire.params import SAME_INSTANT_ORDERS

ENGINES = {"reference": make_reference_env, "fast": make_env}
HOLD = 5
FAR = np.array([0.0, 0.0])  # the origin: no fire within 0.98 m


class Script:
    """Agent i's k-th decision is scripts[i][k] (the last entry repeats)."""

    def __init__(self, scripts: list[list[int]]):
        self.scripts = scripts

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        return np.array([self.scripts[i][min(k, len(self.scripts[i]) - 1)]
                         for i, k in zip(batch.agent, batch.index)], dtype=np.int64)


def run(engine: str, cfg: WildfireConfig, starts, holds, scripts, count_races: bool = False):
    h = np.full((1, cfg.n_agents, cfg.hold_table_size), 3.0)
    for i, hs in enumerate(holds):
        h[0, i, :len(hs)] = hs
    draws = EpisodeDraws(np.array([starts], dtype=float), h)
    return ENGINES[engine](cfg, count_races).simulate(Script(scripts), draws)


def path(r, agent):
    p = int(np.flatnonzero(r.path_agent == agent)[0])
    return slice(r.path_start[p], r.path_start[p + 1])


FIRE0 = fire_positions()[0]
STATUS0 = 2 + 3  # status of the closest fire in the observation
HEALTH0 = 2 + 4


def test_fire_layout():
    f = fire_positions()
    assert f.shape == (9, 2)
    np.testing.assert_allclose(f[:3], [[-0.01, 1.0], [0.01, 1.0],
                                       [0, 1 - 0.02 * np.sin(np.pi / 3)]])
    np.testing.assert_allclose(np.linalg.norm(f[:3].mean(0)), 1 - 0.02 * np.sin(np.pi / 3) / 3)
    # every pair within a cluster is 0.02 m apart; clusters are rotations by 120 deg
    for c in range(3):
        d = np.linalg.norm(f[3 * c:3 * c + 3, None] - f[None, 3 * c:3 * c + 3], axis=-1)
        np.testing.assert_allclose(d[np.triu_indices(3, 1)], 0.02)
    rot = np.array([[-0.5, -np.sqrt(3) / 2], [np.sqrt(3) / 2, -0.5]])
    np.testing.assert_allclose(f[:3] @ rot.T, f[3:6], atol=1e-12)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("order", SAME_INSTANT_ORDERS)
def test_c9_fs1_health_3_needs_a_second_hold_2_9999_does_not(engine, order):
    """UAV 0 starts on fire 0, holds 2.9 s from t = 1e-5, then flies off (if it still can).

    FS-1, T_health = 3.0: the fire is planned out at ceil(3.00001) = 4 but the hold ends at
    ceil(2.90001) = 3; the UAV sees the fire alive, flies away, leaves the party: the fire survives.
    FS-1, T_health = 2.9999: the fire is out at ceil(2.99991) = 3, the instant the hold ends. The
    released order puts the fire out before the UAV observes (the hold's end reaches the UAV two
    events later, the fire's end one), and its r_ext belongs to the hold. In scheduling order the
    hold's end, scheduled first, comes first: the UAV sees the fire alive, and (Q4 off) the fire's
    end interrupts its decision latency: the fly is dropped. One hold suffices either way.
    """
    others = [FAR, FAR]
    released = order == "released"
    for t_health, out in ((3.0, False), (2.9999, True)):
        cfg = WildfireConfig(dt=1.0, t_health=t_health, same_instant_order=order,
                             quirk_q4_latency_not_interrupted=released)
        r = run(engine, cfg, [FIRE0] + others, [[2.9]], [[HOLD, 3], [HOLD], [HOLD]])
        p0 = path(r, 0)
        t = r.info["decision_time"][p0]
        assert t[1] == pytest.approx(3.0, abs=1e-9)
        assert (r.episode_return[0] > 0) == out
        # the observed health at 3: the party of one spent 2.99999 UAV-seconds (Q3: unclamped)
        assert r.obs[p0][1, HEALTH0] == pytest.approx(t_health - 2.99999, abs=1e-9)
        if not out:
            assert r.obs[p0][1, STATUS0] == 1.0
            assert r.rewards[p0][0] == 0.0
        elif released:
            assert r.obs[p0][1, STATUS0] == 0.0  # out before the UAV observed
            assert r.rewards[p0][0] == pytest.approx(np.exp(-cfg.gamma * (3.0 - 1e-5)))
            assert t[2] - t[1] > 1.0  # the fly was not dropped
        else:
            assert r.obs[p0][1, STATUS0] == 1.0  # seen alive at the hold's end
            assert r.rewards[p0][0] == 0.0
            # accrued in the latency (Q5 on): discounted from the hold's start, 1e-5
            assert r.rewards[p0][1] == pytest.approx(np.exp(-cfg.gamma * (3.0 - 1e-5)))
            assert t[2] == pytest.approx(3.0, abs=1e-9)  # interrupted within the latency
            assert r.durations[p0][1] == pytest.approx(0.0, abs=1e-9)
            assert r.obs[p0][2, STATUS0] == 0.0
    # In ED the same 2.9 s hold ends with 0.1 UAV-seconds left, whatever the 1e-4 difference.
    for t_health in (3.0, 2.9999):
        r = run(engine, WildfireConfig(t_health=t_health, same_instant_order=order),
                [FIRE0] + others, [[2.9]], [[HOLD, 3], [HOLD], [HOLD]])
        assert r.episode_return[0] == 0.0


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("order", SAME_INSTANT_ORDERS)
@pytest.mark.parametrize("q3", [True, False])
def test_fs_extinguish_after_the_health_ran_out(engine, order, q3):
    """FS-1, T_health 2.5: UAV 0 holds 2.9 s on fire 0 from 1e-5. The health runs out at 2.50001,
    but the fire's rounded end is 3, the instant the hold ends. Released order: the fire is out
    when the UAV observes; scheduling order: the UAV sees it alive. Either way its observed health
    is 2.5 - 2.99999 with Q3, 0 without."""
    cfg = WildfireConfig(dt=1.0, t_health=2.5, same_instant_order=order,
                         quirk_q3_unclamped_health=q3)
    r = run(engine, cfg, [FIRE0, FAR, FAR], [[2.9]], [[HOLD, HOLD], [HOLD], [HOLD]])
    p0 = path(r, 0)
    assert r.info["decision_time"][p0][1] == pytest.approx(3.0, abs=1e-9)
    assert r.obs[p0][1, STATUS0] == (0.0 if order == "released" else 1.0)
    assert r.obs[p0][1, HEALTH0] == pytest.approx(-0.49999 if q3 else 0.0, abs=1e-9)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("order", SAME_INSTANT_ORDERS)
@pytest.mark.parametrize("q4", [True, False])
@pytest.mark.parametrize("q5", [True, False])
def test_fire_out_during_a_uavs_latency(engine, order, q4, q5):
    """ED. UAV 0 holds on fire 0 from 1e-5: the fire is out at 3.00001. UAV 1 flies to fire 0 from
    0.044999925 m away, arriving at 1e-5 + 2.999995 = 3.000005, so the fire goes out during its
    decision latency. Q4: it is not interrupted and carries out its hold at 3.000015; without Q4
    it decides again at 3.00001. Its r_ext, accrued in the latency, belongs to the decision it made
    on arrival; Q5 discounts it from the flight's start (1e-5), else from that observation."""
    cfg = WildfireConfig(same_instant_order=order, quirk_q4_latency_not_interrupted=q4,
                         quirk_q5_discount_from_action_start=q5)
    start1 = FIRE0 - np.array([0.044999925, 0.0])
    r = run(engine, cfg, [FIRE0, start1, FAR], [[5.0], [5.0]], [[HOLD], [0, HOLD], [HOLD]])
    p1 = path(r, 1)
    t = r.info["decision_time"][p1]
    arrival = 1e-5 + 0.044999925 / cfg.v_uav
    assert t[1] == pytest.approx(arrival, abs=1e-12)
    assert r.obs[p1][1, STATUS0] == 1.0  # alive when it arrived
    if q4:
        assert t[2] == pytest.approx(arrival + 1e-5 + 5.0, abs=1e-9)  # the hold was carried out
    else:
        assert t[2] == pytest.approx(3.00001, abs=1e-12)  # dropped: decides again at once
        assert r.obs[p1][2, STATUS0] == 0.0
    since = 3.00001 - (1e-5 if q5 else arrival)
    assert r.rewards[p1][1] == pytest.approx(np.exp(-cfg.gamma * since), abs=1e-12)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("order", SAME_INSTANT_ORDERS)
@pytest.mark.parametrize("q3", [True, False])
def test_a_dead_fires_observed_health_drains(engine, order, q3):
    """UAVs 0 and 1 put fire 0 out at rate 2 (at 1.50001); nobody leaves the party of a fire that
    is out, so with Q3 its observed health keeps falling at rate 2: UAV 0 holds 1 s more and sees
    -2 * 1.00001 at 2.50002. Without Q3 a fire that is out shows 0."""
    cfg = WildfireConfig(same_instant_order=order, quirk_q3_unclamped_health=q3)
    r = run(engine, cfg, [FIRE0, FIRE0, FAR], [[10.0, 1.0], [10.0, 10.0]],
            [[HOLD, HOLD, 3], [HOLD, HOLD], [HOLD]])
    p0 = path(r, 0)
    np.testing.assert_allclose(r.info["decision_time"][p0][1:3], [1.50001, 2.50002], atol=1e-12)
    assert r.obs[p0][1, STATUS0] == 0.0 and r.obs[p0][2, STATUS0] == 0.0
    assert r.obs[p0][1, HEALTH0] == pytest.approx(0.0, abs=1e-12)
    assert r.obs[p0][2, HEALTH0] == pytest.approx(-2.00002 if q3 else 0.0, abs=1e-12)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("q1", [True, False])
def test_quirk_q1_stale_attack(engine, q1):
    """Hold 1 s on fire 0, 'fly' to it (distance 0: leaves the extinguish party), hold again.
    With Q1 the second hold rejoins nothing and the fire never goes out; without, it does."""
    cfg = WildfireConfig(quirk_q1_stale_attack=q1)
    r = run(engine, cfg, [FIRE0, FAR, FAR], [[1.0] * 5], [[HOLD, 0, HOLD], [HOLD], [HOLD]])
    p0 = path(r, 0)
    assert r.obs[p0][2, HEALTH0] == pytest.approx(2.0, abs=1e-4)  # 1 UAV-second spent
    assert (r.episode_return[0] == 0.0) == q1
    if not q1:
        # the party worked from 1e-5 until the fly at 1.00002 (latency included): 1.99999 left,
        # spent by the hold that rejoins at 1.00003
        assert r.info["decision_time"][p0][4] == pytest.approx(3.00002, abs=1e-9)
        assert r.obs[p0][4, STATUS0] == 0.0


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("order", SAME_INSTANT_ORDERS)
@pytest.mark.parametrize("q2", [True, False])
@pytest.mark.parametrize("q5", [True, False])
def test_two_uavs_join_one_party_at_one_instant(engine, order, q2, q5):
    """UAVs 0 and 1 start on fire 0 and hold, both acting at 1e-5: UAV 1 joins a party that has a
    member: penalty for the party (Q2) or for everyone. The fire re-plans with both (in the
    released order the two changes make one restart of its burn) and goes out at rate 2."""
    cfg = WildfireConfig(quirk_q2_penalty_party_only=q2, same_instant_order=order,
                         quirk_q5_discount_from_action_start=q5)
    r = run(engine, cfg, [FIRE0, FIRE0, FAR], [[10.0], [10.0], [10.0]],
            [[HOLD, 3], [HOLD, 3], [HOLD]])
    returns = [r.rewards[path(r, i)].sum() for i in range(3)]
    np.testing.assert_allclose(r.info["decision_time"][path(r, 0)][1], 1.50001, atol=1e-12)
    third = 1.0 if q2 else -19.0
    disc = lambda t: np.exp(-cfg.gamma * t)  # noqa: E731
    # the penalty at 1e-5, the fire at 1.5 + 1e-5. Q5 discounts from the action's start, 1e-5:
    # UAV 2, still in its latency when UAV 1 joins, from its previous action's start, 0.
    pen, fire = (disc(0.0), disc(1.5)) if q5 else (disc(1e-5), disc(1.5 + 1e-5))
    expect = [-20 * pen + fire] * 2 + [fire + (0 if q2 else -20 * disc(1e-5))]
    np.testing.assert_allclose(returns, expect, atol=1e-12)
    assert r.episode_return[0] == pytest.approx((-19 - 19 + third) / 3)


@pytest.mark.parametrize("n_clusters", [1, 2, 3, 4, 24])
def test_clusters_are_rotations_of_cluster_a(n_clusters):
    """n_clusters clusters of three: cluster k is cluster A rotated by k 360/n_clusters degrees;
    3 is the paper's layout, bit for bit."""
    cfg = WildfireConfig(n_clusters=n_clusters, n_observed=3)
    f = fire_positions(cfg)
    assert f.shape == (3 * n_clusters, 2) == (cfg.n_fires, 2)
    for k in range(n_clusters):
        a = 2 * np.pi * k / n_clusters
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        np.testing.assert_allclose(f[:3] @ rot.T, f[3 * k:3 * k + 3], atol=1e-12)
    if n_clusters == 3:
        assert fire_positions(cfg).tobytes() == fire_positions().tobytes()


@pytest.mark.parametrize("fields, param", [
    (dict(n_clusters=1), "--n-observed"), (dict(n_clusters=0), "--n-clusters"),
    (dict(n_clusters=2.5), "--n-clusters"),
    (dict(fire_out_first=False, same_instant_order="scheduling"), "--no-fire-out-first")])
def test_layouts_and_orders_that_cannot_be_built(fields, param):
    with pytest.raises(ValueError, match=param):
        WildfireConfig(**fields)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("fire_out_first", [True, False])
@pytest.mark.parametrize("q4", [True, False])
def test_a_hold_that_ends_as_its_fire_goes_out(engine, fire_out_first, q4):
    """FS-1, T_health = 2.9999: UAV 0 holds 2.9 s on fire 0 from 1e-5; the hold ends and the fire
    goes out at 3 (claim X4). Released order (fire_out_first): the fire is out when the UAV
    observes, and its r_ext belongs to the hold. Reversed: the UAV observes the fire alive (Q3:
    2.9999 - 2.99999 left), then the fire goes out in its latency; its r_ext belongs to the new
    decision, discounted from the hold's start (Q5); with Q4 the UAV flies as it decided, without
    it the decision is dropped and it decides again at 3."""
    cfg = WildfireConfig(dt=1.0, t_health=2.9999, fire_out_first=fire_out_first,
                         quirk_q4_latency_not_interrupted=q4)
    r = run(engine, cfg, [FIRE0, FAR, FAR], [[2.9]], [[HOLD, 3], [HOLD], [HOLD]])
    p0 = path(r, 0)
    t, rewards, obs = r.info["decision_time"][p0], r.rewards[p0], r.obs[p0]
    fire = np.exp(-cfg.gamma * (3.0 - 1e-5))
    assert t[1] == pytest.approx(3.0, abs=1e-9) and r.episode_return[0] > 0
    assert obs[1, HEALTH0] == pytest.approx(2.9999 - 2.99999, abs=1e-9)
    if fire_out_first:
        assert obs[1, STATUS0] == 0.0
        assert rewards[0] == pytest.approx(fire) and rewards[1] == 0.0
    else:
        assert obs[1, STATUS0] == 1.0
        assert rewards[0] == 0.0 and rewards[1] == pytest.approx(fire)
    if fire_out_first or q4:  # the fly was carried out
        assert t[2] - t[1] > 1.0
    else:
        assert t[2] == pytest.approx(3.0, abs=1e-9) and obs[2, STATUS0] == 0.0


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("fire_out_first", [True, False])
def test_the_reversed_order_leaves_other_instants_alone(engine, fire_out_first):
    """ED: the same hold ends at 2.90001 with the fire alive, and nothing else happens at one
    instant: both orders give the same episode."""
    cfg = WildfireConfig(t_health=2.9999, fire_out_first=fire_out_first)
    r = run(engine, cfg, [FIRE0, FAR, FAR], [[2.9]], [[HOLD, 3], [HOLD], [HOLD]])
    same = run(engine, WildfireConfig(t_health=2.9999), [FIRE0, FAR, FAR], [[2.9]],
               [[HOLD, 3], [HOLD], [HOLD]])
    np.testing.assert_array_equal(r.obs, same.obs)
    np.testing.assert_array_equal(r.rewards, same.rewards)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("dt, races", [(1.0, 132), (None, 0)])
def test_races_are_instants_that_rounding_made_shared(engine, dt, races):
    """Four UAVs wait away from every fire from 1e-5. UAVs 0 and 1 first 2.5 s and 2.7 s: FS-1
    puts both ends at 3, a race; then both wait 3 s at a time, from one instant, so FS-1 keeps
    them together (at 3 + 4k, 66 times before T_max = 264.9) while ED keeps them 0.2 s apart:
    each of those instants is a race, and so is each instant 1e-5 later, where both decision
    latencies end. UAVs 2 and 3 wait 3 s at a time from 1e-5, together in ED as well (at
    4 + 4k): never a race. ED: none."""
    cfg = WildfireConfig(dt=dt, n_agents=4)
    r = run(engine, cfg, [FAR] * 4, [[2.5], [2.7]], [[HOLD]] * 4, count_races=True)
    assert r.info["races"].tolist() == [races]
    times = [r.info["decision_time"][path(r, i)] for i in range(4)]
    np.testing.assert_array_equal(times[2], times[3])
    assert np.isin(times[0], times[1]).sum() == (67 if dt else 1)  # with the start, at 0


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("t_health, races", [(2.9999, 1), (3.0, 0)])
@pytest.mark.parametrize("fire_out_first", [True, False])
def test_a_fire_out_at_a_holds_rounded_end_is_a_race(engine, t_health, races, fire_out_first):
    """FS-1: UAV 0 holds 2.9 s on fire 0 from 1e-5 (due 2.90001, at 3). T_health 2.9999: the fire
    is due out at 2.99991, also at 3: a race, whatever the order. T_health 3.0: due at 3.00001, at
    4, but UAV 0 flies off at 3.00001 and the fire waits for a party: no race. The others hold
    10 s and 20 s alone; the episode ends at UAV 1's second decision's end (max_decisions 2)."""
    cfg = WildfireConfig(dt=1.0, t_health=t_health, fire_out_first=fire_out_first,
                         max_decisions=2)
    r = run(engine, cfg, [FIRE0, FAR, FAR], [[2.9], [10.0], [20.0]], [[HOLD, 3], [HOLD], [HOLD]],
            count_races=True)
    assert r.info["races"].tolist() == [races]
    assert r.info["end_time"][0] == pytest.approx(15.0)
