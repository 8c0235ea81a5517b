"""The renewal process's three simulators: hand cases, and where their semantics must coincide."""

from __future__ import annotations

import numpy as np
import pytest

from repro.core.errors import UsageError
from repro.envs.renewal import (StreamDraws, draw_inter_event_times, simulate_events,
                                simulate_steps)
from repro.envs.renewal.distributions import DISTRIBUTIONS


def draws_of(*agents: list[float]) -> StreamDraws:
    offsets = np.concatenate([[0], np.cumsum([len(a) for a in agents])]).astype(np.int64)
    return StreamDraws(np.concatenate([np.asarray(a, float) for a in agents]), offsets)


# Agent 0 acts at 1, 2, 3; agent 1 at 1.5, 3 (a tie at t = 3, which both reach by exact sums).
HAND = draws_of([1.0, 1.0, 1.0, 1.0], [1.5, 1.5, 1.5])


def test_event_driven_hand_case_ties_in_scheduling_order():
    out = simulate_events(HAND, 3.2)
    # Agent 1 scheduled its t=3 event at t=1.5, before agent 0 did (at t=2):
    # SimPy processes it first.
    assert out.agents.tolist() == [0, 1, 0, 1, 0]
    assert out.times.tolist() == [1.0, 1.5, 2.0, 3.0, 3.0]
    assert out.count.tolist() == [3, 2]
    # Score: others' events so far, summed over own events: agent 0 reads 0, 1, 2;
    # agent 1 reads 1, 2.
    assert out.score.tolist() == [3, 3]
    assert (out.events, out.tied_events, out.steps, out.agent_visits) == (5, 1, 0, 0)


def test_tie_order_changes_the_outcome():
    out = simulate_events(HAND, 3.2, tie_order="agent")
    assert out.agents.tolist() == [0, 1, 0, 0, 1]
    assert out.score.tolist() == [2, 4]


def test_time_stepped_hand_case_counts_steps_and_visits():
    out = simulate_steps(HAND, 3.2, 0.5)
    assert out.agents.tolist() == [0, 1, 0, 0, 1]
    assert out.times.tolist() == [1.0, 1.5, 2.0, 3.0, 3.0]
    assert out.score.tolist() == [2, 4]
    assert (out.steps, out.agent_visits) == (7, 14)  # t = 0, 0.5, ..., 3.0 < 3.2; two agents each


def test_events_at_the_duration_are_not_processed():
    assert simulate_events(HAND, 3.0).times.tolist() == [1.0, 1.5, 2.0]
    out = simulate_steps(HAND, 3.0, 0.5)
    assert out.times.tolist() == [1.0, 1.5, 2.0]
    assert (out.steps, out.agent_visits) == (6, 12)


def test_rounding_puts_events_on_the_grid():
    out = simulate_events(draws_of([0.3, 0.3, 0.3, 0.3]), 1.2, dt=0.25)
    assert out.times.tolist() == [0.5, 1.0]  # ceil(0.3/0.25) = 2 steps, from every grid point


def test_a_used_up_stream_stops_its_agent():
    draws = draws_of([1.0], [0.5, 0.5, 0.5, 0.5, 0.5])
    for out in (simulate_events(draws, 2.2), simulate_steps(draws, 2.2, 0.5)):
        assert out.count.tolist() == [1, 4]


@pytest.mark.parametrize("key", sorted(DISTRIBUTIONS))
@pytest.mark.parametrize("dt", [0.05, 0.5, 2.0])
def test_time_stepped_equals_rounding_simulator_with_the_same_tie_order(key, dt):
    draws = draw_inter_event_times(DISTRIBUTIONS[key], 6, 40.0, np.random.SeedSequence(7))
    fs = simulate_events(draws, 40.0, dt, tie_order="agent")
    ts = simulate_steps(draws, 40.0, dt)
    assert fs.events > 10
    np.testing.assert_array_equal(ts.agents, fs.agents)
    np.testing.assert_array_equal(ts.times, fs.times)
    np.testing.assert_array_equal(ts.count, fs.count)
    np.testing.assert_array_equal(ts.score, fs.score)
    if dt >= 0.5:
        assert fs.tied_events > 0  # the case exercises the tie order


def test_event_driven_is_the_limit_of_the_rounding_simulator():
    duration = 30.0
    draws = draw_inter_event_times(DISTRIBUTIONS["exponential"], 4, duration,
                                   np.random.SeedSequence(3))
    ed = simulate_events(draws, duration)
    gap = np.diff(ed.times).min()
    dt = 1e-9
    assert gap > ed.count.max() * dt  # rounding drifts each agent by < dT per event: no reordering
    fs = simulate_events(draws, duration, dt)
    np.testing.assert_array_equal(fs.agents, ed.agents)
    np.testing.assert_array_equal(fs.score, ed.score)
    assert np.all((fs.times >= ed.times) & (fs.times - ed.times <= ed.count.max() * dt))
    # ... while a coarse grid does reorder and change the outcome.
    assert not np.array_equal(simulate_events(draws, duration, 1.0).score, ed.score)


def test_draws_are_per_agent_and_reach_the_duration():
    dist = DISTRIBUTIONS["gamma"]
    a = draw_inter_event_times(dist, 3, 50.0, np.random.SeedSequence(11))
    b = draw_inter_event_times(dist, 5, 50.0, np.random.SeedSequence(11))
    for i in range(a.n_agents):
        mine = a.delays[a.offsets[i]:a.offsets[i + 1]]
        assert mine.sum() >= 50.0 > mine[:-1].sum()  # just enough draws
        # Agent i's stream does not depend on how many agents there are.
        np.testing.assert_array_equal(mine, b.delays[b.offsets[i]:b.offsets[i + 1]])
    c = draw_inter_event_times(dist, 3, 50.0, np.random.SeedSequence(12))
    assert not np.array_equal(a.delays[:5], c.delays[:5])


@pytest.mark.parametrize("call", [
    lambda: simulate_events(HAND, 3.0, dt=-1.0),
    lambda: simulate_events(HAND, 3.0, tie_order="random"),
    lambda: simulate_events(HAND, 0.0),
    lambda: simulate_steps(HAND, 3.0, 0.0),
])
def test_bad_arguments_are_usage_errors(call):
    with pytest.raises(UsageError):
        call()
