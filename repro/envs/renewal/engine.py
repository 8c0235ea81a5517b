"""N agents, each acting at the events of its own renewal process, for a fixed simulated duration.

Agent i's inter-event times are i.i.d. draws from p(t), pre-drawn from its own random stream, so
every simulator consumes exactly the same draws. At each of its events an agent acts: it reads how
many events the *other* agents have had so far and adds that to its score, then counts its own
event. The scores therefore depend on the order in which events are processed, which is what race
conditions corrupt.

Three simulators:

- ``simulate_events(draws, T)``: event-driven (ED). A binary heap of the agents' next event times;
  events are processed in time order, and the clock jumps from event to event.
- ``simulate_events(draws, T, dt)``: the rounding fixed-step simulator used for training
  (docs/semantics.md section 2.3): every delay d scheduled at time ``now`` ends at ceil((now +
  d)/dT) dT instead. It still jumps from event to event, so its cost does not depend on dT. Events
  at the same instant are processed in scheduling order, as SimPy does (``tie_order="scheduled"``),
  or in agent order (``tie_order="agent"``, the order of the time-stepped simulator).
- ``simulate_steps(draws, T, dt)``: genuinely time-stepped (TS). The clock advances by dT and every
  agent is visited at every step to see whether its event is due; the events due in one step are
  processed in agent order. With ``tie_order="agent"`` it reproduces the rounding simulator exactly.

An event at time t is processed only if t < T (SimPy's ``run(until=T)`` stops before events at T).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from repro.core.errors import require
from repro.core.event_queue import (MAX_WHO, NORMAL, event_key, heap_pop, heap_push,
                                    heap_replace_first, key_fields)
from repro.core.fixed_step import fs_step, fs_time
from repro.core.rollout import children

if TYPE_CHECKING:
    from repro.envs.renewal.distributions import Distribution

TIE_SCHEDULED = 0
"""Same-instant events in the order they were scheduled (SimPy's order)."""
TIE_AGENT = 1
"""Same-instant events in agent-index order (the time-stepped simulator's visiting order)."""
TIE_ORDERS = {"scheduled": TIE_SCHEDULED, "agent": TIE_AGENT}

NEVER = np.iinfo(np.int64).max
"""Due step of an agent whose pre-drawn stream is used up."""


@dataclass(frozen=True)
class StreamDraws:
    """Every agent's pre-drawn inter-event times, stored flat."""

    delays: np.ndarray
    """(D,) float64 inter-event times, agent after agent."""
    offsets: np.ndarray
    """(N+1,) int64: agent i's delays, in order, are delays[offsets[i]:offsets[i+1]]."""

    @property
    def n_agents(self) -> int:
        return len(self.offsets) - 1


def draw_inter_event_times(dist: Distribution, n_agents: int, duration: float,
                           stream: np.random.SeedSequence) -> StreamDraws:
    """Each agent draws from its own child of ``stream`` until its delays add up to ``duration``.

    Rounding only delays events, so no simulator needs more draws than the event-driven one.
    """
    require(n_agents >= 1, "n_agents", "an integer >= 1", n_agents)
    require(duration > 0, "duration", "> 0", duration)
    chunk = int(duration / dist.mean) + 16
    per_agent = []
    for ss in children(stream, n_agents):
        rng = np.random.default_rng(ss)
        parts, total = [], 0.0
        while total < duration:
            parts.append(dist.sample(rng, (1, chunk)).ravel())
            total += float(parts[-1].sum())
        delays = np.concatenate(parts)
        keep = int(np.searchsorted(np.cumsum(delays), duration)) + 1
        per_agent.append(delays[:keep])
    offsets = np.concatenate([[0], np.cumsum([len(d) for d in per_agent])]).astype(np.int64)
    return StreamDraws(np.concatenate(per_agent).astype(np.float64), offsets)


@dataclass(frozen=True)
class Outcome:
    """What one simulation produced and what it cost."""

    agents: np.ndarray
    """(E,) int64 acting agent of every processed event, in processing order."""
    times: np.ndarray
    """(E,) float64 simulated time of every processed event."""
    count: np.ndarray
    """(N,) int64 events of each agent."""
    score: np.ndarray
    """(N,) int64 per-agent result: over its events, the sum of the others' event counts so far."""
    steps: int
    """Clock advances of the time-stepped simulator (0 for the event simulators)."""
    agent_visits: int
    """Agent checks of the time-stepped simulator, one per agent per step (0 for the others)."""

    @property
    def events(self) -> int:
        return len(self.agents)

    @property
    def tied_events(self) -> int:
        """Events processed at the same instant as the event before them (races)."""
        return int(np.count_nonzero(np.diff(self.times) == 0.0))


# --- Kernels -------------------------------------------------------------------------------------

@njit(cache=True)
def _take(delays, offsets, next_draw, i):
    """Agent i's next pre-drawn delay (advancing its cursor), or -1.0 once its stream is used up."""
    j = next_draw[i]
    if j == offsets[i + 1]:
        return -1.0
    next_draw[i] = j + 1
    return delays[j]


@njit(cache=True)
def _act(i, t, count, score, seq_agent, seq_time, n_done):
    """Agent i acts at time t; returns the number of events processed so far."""
    score[i] += n_done - count[i]
    count[i] += 1
    seq_agent[n_done] = i
    seq_time[n_done] = t
    return n_done + 1


@njit(cache=True)
def _key(i, scheduled, tie_order):
    """The event key of agent i's next event, the ``scheduled``-th scheduled: same-instant events
    in scheduling order or in agent order (unique either way: an agent has one pending event)."""
    return event_key(NORMAL, scheduled if tie_order == TIE_SCHEDULED else i, 0, i)


@njit(cache=True)
def _simulate_events(delays, offsets, duration, dt, tie_order):
    n = offsets.size - 1
    seq_agent = np.empty(delays.size, np.int64)
    seq_time = np.empty(delays.size, np.float64)
    count = np.zeros(n, np.int64)
    score = np.zeros(n, np.int64)
    next_draw = offsets[:-1].copy()
    # the heap (repro.core.event_queue) holds each agent's one pending event
    times = np.empty(n, np.float64)
    keys = np.empty(n, np.int64)
    size = 0
    scheduled = 0
    for i in range(n):
        d = _take(delays, offsets, next_draw, i)
        if d >= 0.0:
            heap_push(times, keys, size, fs_time(0.0, d, dt), _key(i, scheduled, tie_order))
            size += 1
            scheduled += 1
    n_done = 0
    while size > 0 and times[0] < duration:
        t = times[0]
        i = key_fields(keys[0])[2]
        n_done = _act(i, t, count, score, seq_agent, seq_time, n_done)
        d = _take(delays, offsets, next_draw, i)
        if d >= 0.0:  # the agent's next event replaces it
            heap_replace_first(times, keys, size, fs_time(t, d, dt), _key(i, scheduled, tie_order))
            scheduled += 1
        else:
            heap_pop(times, keys, size)
            size -= 1
    return seq_agent[:n_done], seq_time[:n_done], count, score


@njit(cache=True)
def _due_step(now, delay, dt):
    """The step of an event after ``delay`` (:func:`repro.core.fixed_step.fs_step`) as an int64,
    which the visits compare a quarter faster than a float; NEVER for no event (delay -1.0) or
    one past the int64 steps, which the simulation never reaches."""
    if delay < 0.0:
        return NEVER
    step = fs_step(now, delay, dt)
    return NEVER if step >= 9.2e18 else np.int64(step)


@njit(cache=True)
def _simulate_steps(delays, offsets, duration, dt):
    n = offsets.size - 1
    seq_agent = np.empty(delays.size, np.int64)
    seq_time = np.empty(delays.size, np.float64)
    count = np.zeros(n, np.int64)
    score = np.zeros(n, np.int64)
    next_draw = offsets[:-1].copy()
    due = np.empty(n, np.int64)
    for i in range(n):
        due[i] = _due_step(0.0, _take(delays, offsets, next_draw, i), dt)
    n_done = 0
    steps = 0
    visits = 0
    k = 0
    while k * dt < duration:
        now = k * dt
        for i in range(n):
            visits += 1
            while due[i] <= k:  # a zero delay is due again in the same step, as in the heap
                n_done = _act(i, now, count, score, seq_agent, seq_time, n_done)
                due[i] = _due_step(now, _take(delays, offsets, next_draw, i), dt)
        steps += 1
        k += 1
    return seq_agent[:n_done], seq_time[:n_done], count, score, steps, visits


# --- Public API ----------------------------------------------------------------------------------

def simulate_events(draws: StreamDraws, duration: float, dt: float = 0.0,
                    tie_order: str = "scheduled") -> Outcome:
    """Event-driven simulation (dt = 0) or the rounding fixed-step simulator (dt > 0)."""
    require(duration > 0, "duration", "> 0", duration)
    require(dt >= 0, "dt", ">= 0 (0: event-driven)", dt)
    require(tie_order in TIE_ORDERS, "tie_order", "one of " + ", ".join(TIE_ORDERS), tie_order)
    require(draws.n_agents <= MAX_WHO, "n_agents", f"at most {MAX_WHO} (event keys)",
            draws.n_agents)
    agents, times, count, score = _simulate_events(draws.delays, draws.offsets, float(duration),
                                                   float(dt), TIE_ORDERS[tie_order])
    return Outcome(agents, times, count, score, steps=0, agent_visits=0)


def simulate_steps(draws: StreamDraws, duration: float, dt: float) -> Outcome:
    """Time-stepped simulation: advance by dt, visit every agent each step (agent order)."""
    require(duration > 0, "duration", "> 0", duration)
    require(dt > 0, "dt", "> 0", dt)
    agents, times, count, score, steps, visits = _simulate_steps(
        draws.delays, draws.offsets, float(duration), float(dt))
    return Outcome(agents, times, count, score, steps=int(steps), agent_visits=int(visits))
