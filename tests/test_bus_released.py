"""The released simulator's rules (B1-B5, docs/semantics.md section 4.9), each in a hand-built
scenario with a known answer, on both engines.

The scenario: 2 buses, 2 stops, 100 s links, nu = 6 pax/min (0.1 pax/s) at both stops, 25% alight
at Stop 1, none at Stop 2, No Holding, horizon 300 s. Worked by hand (latency 1e-5 s; times ~):
Bus 1 starts at Stop 1 at 0 (h = -1), boards round(0.1 * 1e-5) = 0 and leaves at 1e-5; Bus 2
gets Stop 1 at 1e-5 (h = -1) and leaves at 2e-5. Bus 1 reaches Stop 2 at 100 (first arrival by
travel: no reward; Bus 2 has not left Stop 2, so h = -1), boards round(0.1 * t) = 10 (t = 100,
B3), dwells 30 s; Bus 2 queues and gets Stop 2 at 130 (h = 0, no reward) and boards
round(0.1 * 130) = 13. Bus 1 reaches Stop 1 at 230: h = 230 - 0 = 230 s, the first reward,
-0.1 (230 - 360)^2 = -1690; it alights round(0.25 * 10) = round(2.5) = 2 (half to even, B4),
boards round(0.1 * 230) = 23 and dwells 69 s. Bus 2 reaches Stop 1 at 269, queues, gets it at 299
the instant Bus 1 leaves (h = 0): bunched, no reward. Episode return: -1690.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from repro.core.rollout import DecisionBatch
from repro.envs.bus import BusConfig, make_env, make_reference_env
from repro.envs.bus.params import DECISION_LATENCY
from repro.envs.bus.policies import AUTHORS_THRESHOLDS, ThresholdPolicy, no_holding

SCENARIO = BusConfig(n_buses=2, n_stops=2, travel_time=100.0, alight_fraction=(0.25, 0.0),
                     arrival_rate=(6.0, 6.0), horizon=300.0)
ENGINES = pytest.mark.parametrize("make", [make_env, make_reference_env],
                                  ids=["fast", "reference"])


def _run(make, cfg=SCENARIO):
    roll = make(cfg).rollout(no_holding, 1)
    a = roll.info["arrivals"]
    return roll, {k: np.asarray(v) for k, v in a.items()}


@ENGINES
def test_scenario_arrivals(make):
    _, a = _run(make)
    assert a["bus"].tolist() == [0, 1, 0, 1, 0, 1]
    assert a["stop"].tolist() == [0, 0, 1, 1, 0, 0]
    np.testing.assert_allclose(a["time"], [0, 1e-5, 100 + 1e-5, 130 + 2e-5, 230 + 2e-5,
                                           299 + 3e-5], atol=1e-9)
    # h (minutes in the table; NaN = B2's -1): unknown at both starts and at the leader's first
    # arrival by travel
    h = a["h"] * 60
    assert np.isnan(h[:3]).all()
    np.testing.assert_allclose(h[3:], [0.0, 230.0, 0.0], atol=1e-6)
    assert a["load"].tolist() == [0, 0, 0, 0, 10, 13]
    assert a["board"].tolist() == [0, 0, 10, 13, 23, 0]
    assert a["alight"].tolist() == [0, 0, 0, 0, 2, 3]


@ENGINES
def test_scenario_rewards(make):
    """Only the leader's second arrival by travel is rewarded: first arrivals and the bunched
    follower's zero-headway arrival give nothing (B1; pax/s and seconds)."""
    cfg = dataclasses.replace(SCENARIO, gamma=0.0)
    roll, _ = _run(make, cfg)
    assert roll.episode_return[0] == pytest.approx(-1690.0, rel=1e-9)
    # every agent accrues every reward
    np.testing.assert_allclose(roll.discounted_path_returns(0.0), -1690.0, rtol=1e-9)


@ENGINES
def test_scenario_observations(make):
    """Bus 1 sees h = -1 through its first cycle; the observation's last entry is the time since
    the bus's previous action started (B5: 1e-5 s after its observation)."""
    roll, _ = _run(make)
    obs0 = roll.obs[roll.path_start[0]:roll.path_start[1]]
    np.testing.assert_allclose(obs0[:, 1], [-1.0, -1.0, 230.0], atol=1e-6)
    np.testing.assert_allclose(obs0[:, 3], [0.0, 100.0, 130.0], atol=1e-6)
    np.testing.assert_allclose(roll.durations[0], 100.0, atol=1e-9)
    obs1 = roll.obs[roll.path_start[1]:roll.path_start[2]]
    assert obs1[0, 3] == pytest.approx(DECISION_LATENCY)  # Bus 2's first decision: the time


@ENGINES
def test_rounding_switch(make):
    """At a load of 10 and 25% alighting, U = round(2.5): 2 half to even (B4), 3 half up."""
    for b4, alight in ((True, 2), (False, 3)):
        _, a = _run(make, dataclasses.replace(SCENARIO, b4_round_half_even=b4))
        assert a["alight"][4] == alight


@ENGINES
def test_reward_switch(make):
    """Without B1 every visit is penalised in minutes, the bunched arrival too (h = 0 there)."""
    cfg = dataclasses.replace(SCENARIO, gamma=0.0, b1_reward=False)
    roll, a = _run(make, cfg)
    h_min = np.where(np.isnan(a["h"]), -1 / 60, a["h"])
    nu = np.asarray(cfg.arrival_rate)[a["stop"]]
    np.testing.assert_allclose(roll.episode_return[0],
                               -(nu * (h_min - cfg.headway) ** 2).sum(), rtol=1e-12)
    assert (-nu[-1] * (0 - cfg.headway) ** 2) == -216.0


def _batch(h):
    n = len(h)
    return DecisionBatch(obs=np.c_[np.zeros(n), h, np.zeros((n, 2))], episode=np.zeros(n, int),
                         agent=np.zeros(n, int), index=np.zeros(n, int))


def test_threshold_rule():
    """a = the number of thresholds strictly above h: h = -1 holds longest, h = T_j is above it."""
    t1, t2, t3 = AUTHORS_THRESHOLDS
    pol = ThresholdPolicy(np.array([t2, t1, t3]))  # the authors' (unsorted) order
    h = np.array([-1.0, 0.0, t3, t2 - 1e-9, t2, t1, 1e4])
    assert pol(_batch(h)).tolist() == [3, 3, 2, 2, 1, 0, 0]
    # B2 off: h is observed in minutes, the thresholds stay in seconds
    minutes = ThresholdPolicy(np.array([t1, t2, t3]), headway_in_minutes=True)
    assert minutes(_batch(np.array([-1 / 60, 0.0, 5.0, 7.0, 10.0]))).tolist() == [3, 3, 2, 1, 0]
