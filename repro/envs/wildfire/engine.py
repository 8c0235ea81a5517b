"""The fast wildfire engine: a batch of episodes in numba, one policy call per round.

Each episode keeps an array heap of pending events keyed exactly like SimPy's queue, (time,
priority, sequence number) with interrupts and process starts (URGENT) before timeouts (NORMAL)
at the same instant (events due at the current instant wait in two FIFO now-queues, see
``_push``), and schedules the same events in the same order as
:mod:`repro.envs.wildfire.reference`. Hence same-instant events, which FS simulation makes common,
are processed in the reference's order. In the released order (see the reference's docstring)
SimPy's intermediate events, a sub-process starting, ending or failing, an AnyOf or the end
condition triggering, are zero-delay "hop" events here (``ACT_START`` ... ``END_HOP``), pushed when
SimPy schedules them, or run at once when they would be the next event anyway. An event that a
process no longer waits for (its wait was interrupted, or its fire re-planned) is stale and
skipped, as SimPy skips a triggered event without callbacks.

Processes. ``_advance``'s event loop hands each event to the process it resumes, as SimPy does:
``_uav_event`` (the reference's ``_uav`` and ``_macro_action``), ``_fire_event`` (``_fire`` and
``_burn``) and ``_end_event`` (``_clock``, or the released order's end condition). Each ``yield``
of the model, and the event kinds it is here ("released": only in the released order; hops are
zero-delay):

=====================================================  =============================================
SimPy model (``reference.py``)                         event kinds here
=====================================================  =============================================
``_uav``: ``yield from self._timeout(latency)``        LATENCY
``_uav``: ``env.process(self._macro_action(i))``       ACT_START (released; URGENT hop)
``_macro_action``: ``yield from self._timeout(...)``   ACTION
``_uav``: ``yield env.any_of([action, self.over])``    ACT_END (the action sub-process ended or
                                                       failed), then ANY_OF (released; NORMAL hops)
``_uav``: ``except simpy.Interrupt``                   INT_UAV (URGENT; scheduling order, or in the
                                                       latency without Q4)
``_interrupt``: ``action_procs[i].interrupt()``        INT_ACT (released; URGENT)
``_burn``: ``yield from self._timeout(health/party)``  EXTINGUISH
``_burn``: ``yield self.env.event()`` (no party)       none: ``fire_wait`` is -1
``_party_change``: ``burning.interrupt()``             INT_FIRE (URGENT)
``_fire``: ``yield self.burn_procs[j]``                BURN_END (ended) or BURN_FAIL (failed;
                                                       released; NORMAL hops)
``_fire``: ``env.process(self._burn(j))`` again        BURN_START (released; URGENT hop)
``_fire``: ``yield self.env.timeout(0)``, twice        OUT_WAIT1, OUT_WAIT2 (without fire_out_first)
``_clock``: ``yield env.timeout(t_max)`` (released:    CLOCK
the ``clock`` timeout)
``env.all_of(fire_out) | clock`` triggering            END_HOP (released; ``who`` more hops: the
                                                       last ``fire_out``, the all_of, the "or")
=====================================================  =============================================

``_advance`` records the policy's last actions, then runs every live episode until it is blocked
(its next event is the end of a decision latency whose action the policy has not given yet) or
over. Python then hands all pending observations of the batch to the policy in ONE call and
repeats, also for the rounds of a decision or a few near a rollout's end: under the cap of 1,000
decisions per UAV and episode they are few (acting on them inside the kernel would save 0-20% of
a rollout of a trained policy, CHANGELOG 2026-11-26). Decisions are appended to a flat log and
placed into contiguous paths at the end.

Speed. A rollout of the training batch (600 episodes, about 14,000 decisions and 32,000 events)
takes about 50 rounds, so the per-event cost dominates. An episode's state is one numpy record (a
row of a structured array, ``state_dtype``), and so are the parameters (``params_record``) and each
decision's log row (``log_dtype``): numba hands a record to a function as a bare pointer, whereas an
array, or every array of a tuple, costs a reference-count update per call. A round visits only the
live episodes (a list it compacts), each once, and its first read of an episode misses the cache, so
what tells whether the episode is blocked comes first in the record, and the record is small: the
hold durations stay in the draws' array, a heap entry is 16 bytes (its time and one integer packing
priority, sequence number, kind and subject, whose order is the order of (priority, sequence):
:mod:`repro.core.event_queue`), and the reward of a UAV's running decision accrues in the record. A
log row is written when its decision is observed (observation, time, ids), gets its action at the
next round, and is closed (reward, duration) by the UAV's next observation or the episode's end; the
kernel never reads it back. An observation sorts the fires by distance once and counts the interest
parties once. The policy reads views of the log's new rows; its answers are range-checked in the
kernel (numpy's checks cost more than a small round's simulation). At the end the rows are placed
into paths (:mod:`repro.core.paths`: a row's place is its path's start plus its decision number, no
sort) and gathered by a compiled loop. The state and the log are allocated uninitialised: the
kernels write every field before reading it. The hold durations are drawn for the whole batch up
front (the committed random streams), which costs about a third of a rollout without the policy.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from repro.core.config import numba_record
from repro.core.event_queue import (NORMAL, URGENT, event_key, heap_pop, heap_push,
                                    key_fields)
from repro.core.fixed_step import fs_delay
from repro.core.paths import path_layout, path_order
from repro.core.rollout import BadActions, DecisionBatch, Policy, Rollout, check_actions
from repro.envs.wildfire.params import (DIST, FIRES, HEALTH, INTEREST, LEVEL, OBS_PER_FIRE, OWN_X,
                                        OWN_Y, RACE_TOLERANCE, STATUS, EpisodeDraws,
                                        RunsOnStream, WildfireConfig, draw_episodes,
                                        fire_positions, rank_key)

(LATENCY, ACT_START, ACTION, INT_ACT, ACT_END, ANY_OF, INT_UAV,
 EXTINGUISH, INT_FIRE, BURN_FAIL, BURN_START, BURN_END, OUT_WAIT1, OUT_WAIT2,
 CLOCK, END_HOP) = range(16)
"""Event kinds, numbered by the process they resume (the module docstring's table): a UAV's
(LATENCY to INT_UAV), a fire's (EXTINGUISH to OUT_WAIT2), the episode's end (CLOCK, END_HOP).
The number only tells the kind: an event's place in the queue is its (time, priority, sequence)."""
OK, GROW_LOG, HEAP_FULL, BAD_ACTION = range(4)
"""Status codes of ``_advance``."""
def heap_capacity(cfg: WildfireConfig) -> int:
    """Pending events an episode's heap holds: the live waits (N UAVs, the fires, the clock) and
    stale ones not yet come due; 128 (about ten per process at the paper's sizes), and 8 per
    process beyond that, so that any number of UAVs fits."""
    return max(128, 8 * (cfg.n_agents + len(fire_positions(cfg)) + 1))


def queue_capacity(cfg: WildfireConfig) -> int:
    """Events due now an episode's two now-queues hold each: at most a few per process."""
    return 2 * (cfg.n_agents + len(fire_positions(cfg))) + 8

# Flags inside records are int8 (numba does not support nested boolean arrays); int32 counters and
# indices keep the state record small. In the kernels ``state`` is an episode's state record,
# ``params`` the parameters' record, ``record`` a log row; ``e`` indexes episodes, ``i`` UAVs and
# ``j`` fires.
jit = njit(cache=True)
dispatch = njit(cache=True, inline="always")
"""The event loop's handlers: inlined into the loop, as one body (each call of a compiled function
that takes an array costs reference-count updates, once per event here). The loop itself is
written in :func:`_advance`: as a function of its own, even inlined, it made the engine about 8%
slower (CHANGELOG, 2026-11-26)."""

rank_key_nb = jit(rank_key)


def params_record(cfg: WildfireConfig, count_races: bool = False) -> np.ndarray:
    """The (1,) structured array of the kernels' parameters: the config's fields by name
    (:func:`repro.core.config.numba_record`), then what the kernels derive from them
    (``released_order``: the released same-instant order; the fires and T_max), and whether the
    kernels count races (:class:`WildfireEnv`)."""
    fires = fire_positions(cfg)
    return numba_record(cfg, n_fires=len(fires), t_max=cfg.t_max,
                        released_order=cfg.same_instant_order == "released",
                        count_races=count_races, fires=fires)


def state_dtype(cfg: WildfireConfig) -> np.dtype:
    """One episode's state: scalars, then (N, ...) UAV fields, (K,) fire fields, the event heap."""
    n, k, f8, i8, i4, i1 = (cfg.n_agents, len(fire_positions(cfg)), np.float64, np.int64,
                            np.int32, np.int8)
    return np.dtype([
        # what a round reads of every episode first, to tell whether it is blocked, is adjacent:
        # each episode's first visit of a round misses the cache
        ("done", np.bool_), ("truncated", np.bool_), ("n_alive", i4), ("now", f8), ("t_end", f8),
        ("events", i8),
        ("uav_wait", i8, n), ("act", i8, n),
        # the event heap (repro.core.event_queue): key and time; its size; the next sequence;
        # the now-queues of URGENT and NORMAL events due now (see _push): keys, first, size
        ("heap_key", i8, heap_capacity(cfg)), ("heap_time", f8, heap_capacity(cfg)),
        ("heap_size", i4), ("next_seq", i8),
        ("urgent_queue", i8, queue_capacity(cfg)), ("urgent_head", i4), ("urgent_size", i4),
        ("normal_queue", i8, queue_capacity(cfg)), ("normal_head", i4), ("normal_size", i4),
        # UAV motion
        ("pos", f8, (n, 2)), ("origin", f8, (n, 2)), ("goal", f8, (n, 2)), ("t_dep", f8, n),
        ("length", f8, n), ("flying", i1, n),
        # UAV bookkeeping; the running decision (its action is ``act``, -1 until the policy gave
        # it): its log row, time and discounted reward so far
        ("interest", i4, n), ("attacking", i4, n), ("in_party", i1, n), ("n_holds", i4, n),
        ("rank", i4, (n, cfg.n_observed)), ("n_dec", i4, n), ("returns", f8, n),
        ("running_row", i8, n), ("t_obs", f8, n), ("rew", f8, n), ("t_disc", f8, n),
        # when the UAV joined its interest party (a counter: the party's order); whether it waits
        # its latency; whether its action sub-process is alive (released order), and whether the
        # action ended by an interrupt
        ("joined", i8, n), ("joins", i8), ("in_lat", i1, n), ("acting", i1, n), ("cut", i1, n),
        # fires; whether the burn sub-process is alive (released order)
        ("alive", i1, k), ("health", f8, k), ("t_update", f8, k), ("party", i4, k),
        ("fire_wait", i8, k), ("burning", i1, k),
        # scratch of an observation: the observing UAV's distance to every fire and its ranking
        # key, the fires in ranking order, the size of every fire's interest party
        ("fire_dist", f8, k), ("fire_key", f8, k), ("fire_order", i4, k), ("fire_party", i4, k),
        # the race count (only with ``count_races``, last: the default path never touches it):
        # the exact time of the event being processed (see _exact_time); the exact due times of
        # each UAV's latency and macro-action, and of what cut it; of each fire's extinguishing,
        # and of its latest party change; the races so far; the instant of the latest expiry,
        # the exact due time of the first timeout that expired then, and whether it was counted
        ("exact_now", f8), ("latency_due", f8, n), ("action_due", f8, n), ("cut_due", f8, n),
        ("out_due", f8, k), ("change_due", f8, k), ("races", i8), ("race_time", f8),
        ("race_due", f8), ("race_counted", np.bool_),
    ], align=True)


def log_dtype(obs_dim: int) -> np.dtype:
    """One decision: its observation and action, reward and duration once it closed, its time,
    episode, agent and decision number (int64: the policy gets these as they are)."""
    f8, i8 = np.float64, np.int64
    return np.dtype([("obs", f8, obs_dim), ("time", f8), ("rew", f8), ("dur", f8), ("act", i8),
                     ("ep", i8), ("agent", i8), ("idx", i8)], align=True)


# --- event queue ----------------------------------------------------------------------------------

@jit
def _push(state, delay, prio, kind, who):
    """Schedule an event ``delay`` after now (SimPy: time now + delay); return its sequence.

    An event due now goes to the now-queue of its priority, in order, not the heap: every event
    the heap holds for now was scheduled earlier (sequence numbers grow), so SimPy's order at
    now is the URGENT queue, then the heap's events due now (all NORMAL timeouts), then the NORMAL
    queue. The released order's hops and the interrupts all take the queues."""
    seq = state.next_seq
    state.next_seq = seq + 1
    t = state.now + delay
    key = event_key(prio, seq, kind, who)
    if t != state.now:
        heap_push(state.heap_time, state.heap_key, state.heap_size, t, key)
        state.heap_size += 1
    elif prio == URGENT:
        tail = (state.urgent_head + state.urgent_size) % state.urgent_queue.shape[0]
        state.urgent_queue[tail] = key
        state.urgent_size += 1
    else:
        tail = (state.normal_head + state.normal_size) % state.normal_queue.shape[0]
        state.normal_queue[tail] = key
        state.normal_size += 1
    return seq


@jit
def _next_anyway(state, prio):
    """Whether an event pushed now with priority ``prio`` would be the next one: then a hop can
    run at once instead (the released order's chains of hops mostly do, in ED)."""
    if state.urgent_size > 0:
        return False
    return prio == URGENT or (state.normal_size == 0 and
                              (state.heap_size == 0 or state.heap_time[0] > state.now))


@jit
def _next_source(state):
    """Where the next event is: 0 the URGENT now-queue, 1 the heap, 2 the NORMAL now-queue."""
    if state.urgent_size > 0:
        return 0
    if state.normal_size > 0 and (state.heap_size == 0 or state.heap_time[0] != state.now):
        return 2
    return 1


@jit
def _next_key(state):
    """The key of the next event."""
    src = _next_source(state)
    if src == 0:
        return state.urgent_queue[state.urgent_head]
    return state.normal_queue[state.normal_head] if src == 2 else state.heap_key[0]


@jit
def _pop(state):
    """Remove the next event; return its time and key."""
    src = _next_source(state)
    if src == 0:
        key = state.urgent_queue[state.urgent_head]
        state.urgent_head = (state.urgent_head + 1) % state.urgent_queue.shape[0]
        state.urgent_size -= 1
        return state.now, key
    if src == 2:
        key = state.normal_queue[state.normal_head]
        state.normal_head = (state.normal_head + 1) % state.normal_queue.shape[0]
        state.normal_size -= 1
        return state.now, key
    first = heap_pop(state.heap_time, state.heap_key, state.heap_size)
    state.heap_size -= 1
    return first


# --- model (mirrors reference.WildfireModel method by method) ------------------------------------

@jit
def _dist(ax, ay, bx, by):
    return math.sqrt((bx - ax) * (bx - ax) + (by - ay) * (by - ay))


@jit
def _health_now(state, params, j):
    left = state.health[j] - state.party[j] * (state.now - state.t_update[j])
    if params.quirk_q3_unclamped_health:
        return left
    return max(0.0, left) if state.alive[j] else 0.0


@jit
def _close(state, record, i):
    """UAV i's running decision (its log row ``record``) ends now."""
    record.rew = state.rew[i]
    record.dur = state.now - state.t_obs[i]


@jit
def _position(state, params, i):
    """Where UAV i is now: on its flight's segment, or where it landed."""
    if not state.flying[i]:
        return state.pos[i, 0], state.pos[i, 1]
    length = state.length[i]
    if params.quirk_q6_short_flight_stays and length < params.at_fire_tol:
        return state.origin[i, 0], state.origin[i, 1]
    if length == 0:
        return state.goal[i, 0], state.goal[i, 1]
    frac = min(1.0, params.v_uav * (state.now - state.t_dep[i]) / length)
    return (state.origin[i, 0] + frac * (state.goal[i, 0] - state.origin[i, 0]),
            state.origin[i, 1] + frac * (state.goal[i, 1] - state.origin[i, 1]))


@jit
def _observe(state, params, record, row, e, i):
    """UAV i observes into the log row ``record`` (number ``row``) and waits its decision
    latency."""
    now = state.now
    sojourn = now - state.t_obs[i] if state.n_dec[i] > 0 else 0.0
    x, y = _position(state, params, i)
    o = record.obs
    o[OWN_X], o[OWN_Y] = x, y
    dist, key, order, party = state.fire_dist, state.fire_key, state.fire_order, state.fire_party
    for j in range(params.n_fires):  # insertion sort by (ranking key, index): lower index wins ties
        d = _dist(x, y, params.fires[j, 0], params.fires[j, 1])
        dist[j] = d
        kj = rank_key_nb(d, params.ranking_resolution)
        key[j] = kj
        at = j
        while at > 0 and key[order[at - 1]] > kj:
            order[at] = order[at - 1]
            at -= 1
        order[at] = j
        party[j] = 0
    for a in range(params.n_agents):
        if state.interest[a] >= 0:
            party[state.interest[a]] += 1
    for k in range(params.n_observed):
        best = order[k]
        state.rank[i, k] = best
        base = FIRES + OBS_PER_FIRE * k
        o[base + DIST] = dist[best]
        o[base + LEVEL] = 1.0
        o[base + INTEREST] = party[best]
        o[base + STATUS] = 1.0 if state.alive[best] else 0.0
        o[base + HEALTH] = _health_now(state, params, best)
    o[FIRES + OBS_PER_FIRE * params.n_observed] = sojourn
    record.time = now
    record.ep = e
    record.agent = i
    record.idx = state.n_dec[i]
    state.n_dec[i] += 1
    state.running_row[i] = row
    state.act[i] = -1
    state.t_obs[i] = now
    if not params.quirk_q5_discount_from_action_start:
        state.t_disc[i] = now
    state.rew[i] = 0.0
    state.in_lat[i] = True
    if params.count_races:
        state.latency_due[i] = state.exact_now + params.decision_latency
    state.uav_wait[i] = _push(state, params.decision_latency, NORMAL, LATENCY, i)


@jit
def _accrue(state, params, i, reward):
    state.rew[i] += math.exp(-params.gamma * (state.now - state.t_disc[i])) * reward
    state.returns[i] += reward


@jit
def _party_change(state, params, j, delta):
    if not state.alive[j]:
        return
    now = state.now
    state.health[j] = state.health[j] - state.party[j] * (now - state.t_update[j])
    state.t_update[j] = now
    state.party[j] += delta
    if params.count_races:
        state.change_due[j] = state.exact_now
    if not params.released_order:
        _push(state, 0.0, URGENT, INT_FIRE, j)
    elif state.burning[j]:  # else it ended at this instant: the fire goes out all the same
        _push(state, 0.0, URGENT, INT_FIRE, j)


@jit
def _penalise(state, params, j):
    if state.party[j] < 2:
        return
    for i in range(params.n_agents):
        member = state.in_party[i] and state.attacking[i] == j
        if member or not params.quirk_q2_penalty_party_only:
            _accrue(state, params, i, params.r_pen)


@jit
def _join_interest(state, i, j):
    state.interest[i] = j
    state.joined[i] = state.joins
    state.joins += 1


@jit
def _start_action(state, params, i, a, hold):
    """UAV i starts action a; ``hold`` is its next hold duration (used if a holds)."""
    now = state.now
    if params.quirk_q5_discount_from_action_start:
        state.t_disc[i] = now
    _land(state, params, i, True)  # a cut flight that went on until now
    state.interest[i] = -1
    if a < params.n_observed:
        target = state.rank[i, a]
        _join_interest(state, i, target)
        if state.in_party[i]:
            state.in_party[i] = False
            _party_change(state, params, state.attacking[i], -1)
        if not params.quirk_q1_stale_attack:
            state.attacking[i] = -1
        ox, oy = state.pos[i, 0], state.pos[i, 1]
        gx, gy = params.fires[target, 0], params.fires[target, 1]
        length = _dist(ox, oy, gx, gy)
        state.origin[i, 0], state.origin[i, 1] = ox, oy
        state.goal[i, 0], state.goal[i, 1] = gx, gy
        state.t_dep[i] = now
        state.length[i] = length
        state.flying[i] = True
        duration = length / params.v_uav
    else:
        x, y = state.pos[i, 0], state.pos[i, 1]
        for j in range(params.n_fires):
            if _dist(x, y, params.fires[j, 0], params.fires[j, 1]) < params.at_fire_tol:
                _join_interest(state, i, j)
                if state.attacking[i] != j:
                    state.attacking[i] = j
                    if state.alive[j]:
                        state.in_party[i] = True
                        _party_change(state, params, j, 1)
                        _penalise(state, params, j)
                break
        state.n_holds[i] += 1
        duration = hold
    if params.count_races:
        state.action_due[i] = state.exact_now + duration
    delay = fs_delay(now, duration, params.dt, params.fs_round_negative_delays)
    state.uav_wait[i] = _push(state, delay, NORMAL, ACTION, i)


@jit
def _land(state, params, i, cut):
    """The flight ends now: at its goal if it finished, else where it got to."""
    if not state.flying[i]:
        return
    if cut or (params.quirk_q6_short_flight_stays and state.length[i] < params.at_fire_tol):
        state.pos[i, 0], state.pos[i, 1] = _position(state, params, i)
    else:
        state.pos[i, 0], state.pos[i, 1] = state.goal[i, 0], state.goal[i, 1]
    state.flying[i] = False


@jit
def _replan(state, params, j):
    if state.party[j] == 0:
        state.fire_wait[j] = -1  # idle until the party changes
    else:
        duration = state.health[j] / state.party[j]
        if params.count_races:
            state.out_due[j] = state.exact_now + duration
        delay = fs_delay(state.now, duration, params.dt, params.fs_round_negative_delays)
        state.fire_wait[j] = _push(state, delay, NORMAL, EXTINGUISH, j)


@jit
def _interrupt(state, params, i):
    """A fire UAV i is interested in went out."""
    if params.count_races:
        state.cut_due[i] = state.exact_now
    if state.in_lat[i]:
        if not params.quirk_q4_latency_not_interrupted:
            _push(state, 0.0, URGENT, INT_UAV, i)  # drop the pending decision
    elif not params.released_order:
        _push(state, 0.0, URGENT, INT_UAV, i)
    elif state.acting[i]:  # else it ended at this instant: the UAV will observe
        _push(state, 0.0, URGENT, INT_ACT, i)


@jit
def _extinguish(state, params, j):
    state.alive[j] = False
    state.n_alive -= 1
    for i in range(params.n_agents):
        _accrue(state, params, i, params.r_ext)
    if params.released_order:  # in the order they joined the interest party
        last = np.int64(-1)
        while True:
            nxt, first = -1, np.int64(0)
            for i in range(params.n_agents):
                if (state.interest[i] == j and state.joined[i] > last
                        and (nxt < 0 or state.joined[i] < first)):
                    nxt, first = i, state.joined[i]
            if nxt < 0:
                break
            _interrupt(state, params, nxt)
            last = first
    else:
        for i in range(params.n_agents):
            if state.interest[i] == j:
                _interrupt(state, params, i)


@jit
def _fire_out(state, params, j):
    """Released order: fire j's burn sub-process ended, the fire goes out; after the last one the
    conditions "fire out", "all out", "all out or T_max" trigger in turn."""
    _extinguish(state, params, j)
    if state.n_alive == 0:
        _push(state, 0.0, NORMAL, END_HOP, 2)


@jit
def _burn_ended(state, params, j):
    """Released order: the end of fire j's burn sub-process reaches the fire, which goes out now
    (``fire_out_first``), or waits two zero-delay timeouts first (OUT_WAIT1, OUT_WAIT2), so that
    a UAV whose macro-action ends at this instant observes before (two hops after its timeout)."""
    if params.fire_out_first:
        _fire_out(state, params, j)
    else:
        _push(state, 0.0, NORMAL, OUT_WAIT1, j)


@jit
def _exact_time(state, kind, who):
    """Races: ``exact_now``, the exact time of the event just popped (of ``kind``, about
    ``who``): the due time of the timeout it follows from, as ED would time it along this FS run
    (each due time is the exact time of the event that scheduled it plus the delay before FS
    rounding). A hop or interrupt has the time of the event that caused it."""
    if kind == LATENCY or kind == ACT_START:
        state.exact_now = state.latency_due[who]
    elif kind == ACTION:
        state.exact_now = state.action_due[who]
    elif kind == INT_UAV or kind == INT_ACT:
        state.exact_now = state.cut_due[who]
    elif kind == ACT_END or kind == ANY_OF:
        state.exact_now = state.cut_due[who] if state.cut[who] else state.action_due[who]
    elif kind == EXTINGUISH or kind == BURN_END or kind == OUT_WAIT1 or kind == OUT_WAIT2:
        state.exact_now = state.out_due[who]
    elif kind == INT_FIRE or kind == BURN_FAIL or kind == BURN_START:
        state.exact_now = state.change_due[who]
    elif kind == CLOCK:  # T_max is never rounded
        state.exact_now = state.now


@jit
def _note_expiry(state):
    """A timeout expires now, exactly due at ``exact_now``: the instant (the expiries within
    RACE_TOLERANCE of its first) is a race once one of them was due at another time than its
    first (counted once per instant)."""
    due = state.exact_now
    if abs(state.now - state.race_time) > RACE_TOLERANCE:
        state.race_time = state.now
        state.race_due = due
        state.race_counted = False
    elif abs(due - state.race_due) > RACE_TOLERANCE and not state.race_counted:
        state.races += 1
        state.race_counted = True


@jit
def _end(state):
    """The episode ends now (the event loop then closes every UAV's running decision,
    :func:`_close_running`)."""
    state.done = True
    state.t_end = state.now


@jit
def _close_running(state, log, params):
    """The episode has ended: every UAV's running decision closes."""
    for i in range(params.n_agents):
        _close(state, log[state.running_row[i]], i)


@jit
def _act(state, params, holds, e, i):
    """UAV i starts the action the policy gave it."""
    a = state.act[i]
    hold = holds[e, i, state.n_holds[i] % holds.shape[2]] if a == params.n_observed else 0.0
    _start_action(state, params, i, a, hold)


@jit
def _to_uav(state, log, params, e, row, i, hops):
    """The end of UAV i's macro-action reaches it ``hops`` NORMAL events later (2: the action
    sub-process ending, then the AnyOf; 1: the AnyOf). Returns the next free row."""
    if _next_anyway(state, NORMAL):
        state.events += hops
        return _macro_action_over(state, log, params, e, row, i, state.cut[i])
    _push(state, 0.0, NORMAL, ACT_END if hops == 2 else ANY_OF, i)
    return row


@jit
def _burn_restarts(state, params, j, hops):
    """Fire j's failed burn sub-process restarts ``hops`` events later (2: its failure, NORMAL,
    then its start, URGENT; 1: the start)."""
    if _next_anyway(state, NORMAL if hops == 2 else URGENT):
        state.events += hops
        state.burning[j] = True
        _replan(state, params, j)
    else:
        _push(state, 0.0, NORMAL if hops == 2 else URGENT,
              BURN_FAIL if hops == 2 else BURN_START, j)


@jit
def _macro_action_over(state, log, params, e, row, i, cut):
    """UAV i's macro-action ended (cut: by an interrupt): it observes again (log row ``row``),
    unless that was its last allowed decision; returns the next free row."""
    if not (cut and params.cut_flight_continues):
        _land(state, params, i, cut)
    _close(state, log[state.running_row[i]], i)
    if state.n_dec[i] == params.max_decisions:  # 0 (no limit) never: n_dec >= 1 here
        state.truncated = True
        _end(state)
        return row
    _observe(state, params, log[row], row, e, i)
    return row + 1


@dispatch
def _latency_over(state, params, holds, e, i):
    """UAV i's decision latency is over: it acts, in the released order through its action
    sub-process, whose start is one URGENT hop."""
    state.in_lat[i] = False
    if not params.released_order:
        _act(state, params, holds, e, i)
    else:
        state.acting[i] = True
        if _next_anyway(state, URGENT):
            state.events += 1
            _act(state, params, holds, e, i)
        else:
            _push(state, 0.0, URGENT, ACT_START, i)


@dispatch
def _action_ends(state, log, params, e, row, i, cut):
    """Released order: UAV i's action sub-process ends (``cut``: fails, interrupted, and its
    timeout is stale); returns the next free row."""
    state.acting[i] = False
    state.cut[i] = cut
    if cut:
        state.uav_wait[i] = -1
    return _to_uav(state, log, params, e, row, i, 2)


@dispatch
def _burnt_out(state, params, j):
    """Fire j's extinguish timeout expires: it goes out, or in the released order its burn
    sub-process ends, which reaches the fire one NORMAL hop later."""
    if not params.released_order:
        _extinguish(state, params, j)
        if state.n_alive == 0:
            _end(state)
    else:
        state.burning[j] = False
        if _next_anyway(state, NORMAL):
            state.events += 1
            _burn_ended(state, params, j)
        else:
            _push(state, 0.0, NORMAL, BURN_END, j)


@dispatch
def _count_races(state, seq, kind, who):
    """Races: the exact time of the event just popped (:func:`_exact_time`), and, if it is a
    timeout whose process still waits for it, its expiry (:func:`_note_expiry`)."""
    _exact_time(state, kind, who)
    if (kind == CLOCK or ((kind == LATENCY or kind == ACTION) and seq == state.uav_wait[who])
            or (kind == EXTINGUISH and seq == state.fire_wait[who])):
        _note_expiry(state)


# --- kernels -------------------------------------------------------------------------------------

@jit
def _setup(states, log, used, params_array, starts, slots):
    """Every field of the (uninitialised) states of episodes ``slots`` (their UAVs start at
    ``starts``, in that order), then time 0: every UAV observes (in index order), and the T_max
    clock starts (in the released order before, as the released code creates it before running
    its processes)."""
    params = params_array[0]
    row = used[0]
    for slot in range(len(slots)):
        e = slots[slot]
        state = states[e]
        state.now = 0.0
        state.t_end = np.nan
        state.events = 0
        state.done = False
        state.truncated = False
        state.n_alive = params.n_fires
        state.heap_size = 0
        state.next_seq = 0
        state.urgent_head = state.urgent_size = state.normal_head = state.normal_size = 0
        state.joins = 0
        for i in range(params.n_agents):
            state.pos[i, 0], state.pos[i, 1] = starts[slot, i, 0], starts[slot, i, 1]
            state.flying[i] = False  # origin, goal, t_dep and length are set on take-off
            state.interest[i] = -1
            state.attacking[i] = -1
            state.in_party[i] = False
            state.n_holds[i] = 0
            state.n_dec[i] = 0
            state.uav_wait[i] = -1
            state.joined[i] = 0
            state.acting[i] = False
            state.cut[i] = False
            state.t_disc[i] = 0.0
            # rank, running_row, t_obs, rew, in_lat: set by the first observation
            state.returns[i] = 0.0
        for j in range(params.n_fires):
            state.alive[j] = True
            state.health[j] = params.t_health
            state.t_update[j] = 0.0
            state.party[j] = 0
            state.fire_wait[j] = -1
            state.burning[j] = True  # the burn sub-process waits for a party
        state.exact_now = 0.0
        state.races = 0
        state.race_time = -1.0  # no expiry yet (times are >= 0)
        state.race_counted = False
        if params.released_order:
            _push(state, params.t_max, NORMAL, CLOCK, 0)
        for i in range(params.n_agents):
            _observe(state, params, log[row], row, e, i)
            row += 1
        if not params.released_order:
            _push(state, params.t_max, NORMAL, CLOCK, 0)
    used[0] = row


@jit
def _record_actions(states, log, params, actions, first):
    """Record the actions of log rows first, first + 1, ...; False, and nothing changed, if one is
    out of range (checked here: numpy's checks cost more than a small round's simulation)."""
    for k in range(len(actions)):
        if actions[k] < 0 or actions[k] > params.n_observed:  # the actions are 0..n_observed
            return False
    for k in range(len(actions)):
        record = log[first + k]
        record.act = actions[k]
        state = states[record.ep]
        # else superseded: the end of its latency is stale
        if state.running_row[record.agent] == first + k:
            state.act[record.agent] = actions[k]
    return True


@jit
def _advance(states, live, log, used, params_array, holds, actions, first):
    """Record the round's actions (:func:`_record_actions`; BAD_ACTION if one is out of range),
    then run every live episode until it is blocked (its next event is the end of a decision
    latency whose action is still -1) or over, or until the log (GROW_LOG) or a queue (HEAP_FULL)
    might overflow. Each event goes to the process it resumes (kinds are numbered by process).
    Returns the status and the first row now without an action. ``live[0]`` episodes are live,
    ``live[1:]`` (in order); those that end leave the list, so later rounds do not visit them."""
    params = params_array[0]
    if not _record_actions(states, log, params, actions, first):
        return BAD_ACTION, first
    row, status, n_live = used[0], OK, 0
    room = params.n_agents + 3  # what one event may push, at most
    for q in range(live[0]):
        e = live[1 + q]
        state = states[e]
        while not state.done:
            seq, kind, who = key_fields(_next_key(state))
            if kind == LATENCY and seq == state.uav_wait[who] and state.act[who] < 0:
                break  # the policy has not decided yet
            if row >= len(log):
                status = GROW_LOG
                break
            if (state.heap_size + room > state.heap_key.shape[0]
                    or state.urgent_size + room > state.urgent_queue.shape[0]
                    or state.normal_size + room > state.normal_queue.shape[0]):
                status = HEAP_FULL
                break
            t, key = _pop(state)
            seq, kind, who = key_fields(key)
            state.now = t
            state.events += 1
            if params.count_races:
                _count_races(state, seq, kind, who)
            if kind < EXTINGUISH:
                row = _uav_event(state, log, params, holds, e, row, seq, kind, who)
            elif kind < CLOCK:
                _fire_event(state, params, seq, kind, who)
            else:
                _end_event(state, params, kind, who)
        if state.done:
            _close_running(state, log, params)
        else:
            live[1 + n_live] = e
            n_live += 1
        if status != OK:  # keep the episodes not visited
            for rest in range(q + 1, live[0]):
                live[1 + n_live] = live[1 + rest]
                n_live += 1
            break
    live[0] = n_live
    used[0] = row
    return status, first + len(actions)


@dispatch
def _uav_event(state, log, params, holds, e, row, seq, kind, who):
    """An event of UAV ``who``'s process (the reference's ``_uav`` and ``_macro_action``); a
    timeout it no longer waits for is stale. Returns the next free row."""
    if kind == LATENCY:
        if seq == state.uav_wait[who]:
            _latency_over(state, params, holds, e, who)
    elif kind == ACT_START:
        _act(state, params, holds, e, who)
    elif kind == ACTION:
        if seq == state.uav_wait[who]:
            if params.released_order:
                row = _action_ends(state, log, params, e, row, who, False)
            else:
                row = _macro_action_over(state, log, params, e, row, who, False)
    elif kind == INT_ACT:
        if state.acting[who]:
            row = _action_ends(state, log, params, e, row, who, True)
    elif kind == ACT_END:
        row = _to_uav(state, log, params, e, row, who, 1)
    elif kind == ANY_OF:
        row = _macro_action_over(state, log, params, e, row, who, state.cut[who])
    else:  # INT_UAV
        row = _macro_action_over(state, log, params, e, row, who, True)
    return row


@dispatch
def _fire_event(state, params, seq, kind, who):
    """An event of fire ``who``'s process (the reference's ``_fire`` and ``_burn``); an extinguish
    timeout it no longer waits for is stale."""
    if kind == EXTINGUISH:
        if seq == state.fire_wait[who]:
            _burnt_out(state, params, who)
    elif kind == INT_FIRE:
        if params.released_order:
            if state.burning[who]:  # the burn sub-process fails
                state.burning[who] = False
                state.fire_wait[who] = -1
                _burn_restarts(state, params, who, 2)
        elif state.alive[who]:
            _replan(state, params, who)
    elif kind == BURN_FAIL:  # the fire restarts its burn sub-process
        _burn_restarts(state, params, who, 1)
    elif kind == BURN_START:
        state.burning[who] = True
        _replan(state, params, who)
    elif kind == BURN_END:
        _burn_ended(state, params, who)
    elif kind == OUT_WAIT1:
        _push(state, 0.0, NORMAL, OUT_WAIT2, who)
    else:  # OUT_WAIT2
        _fire_out(state, params, who)


@dispatch
def _end_event(state, params, kind, who):
    """T_max's clock (the reference's ``_clock``, or its timeout in the released order, where the
    condition "all out or T_max" triggers one hop later), or a hop of the released order's end
    condition (END_HOP: ``who`` more to go)."""
    if kind == END_HOP and who > 0:
        _push(state, 0.0, NORMAL, END_HOP, who - 1)
    elif kind == CLOCK and params.released_order:
        _push(state, 0.0, NORMAL, END_HOP, 0)
    else:
        _end(state)


@jit
def _gather(rows, order, obs, actions, rewards, durations, times):
    """The log's rows in path order (``order``, :func:`repro.core.paths.path_order`) into the
    rollout's columns (compiled: numpy's gathers of the records' fields take half as long again)."""
    for d in range(len(order)):
        record = rows[order[d]]
        o = record.obs
        for w in range(obs.shape[1]):
            obs[d, w] = o[w]
        actions[d] = record.act
        rewards[d] = record.rew
        durations[d] = record.dur
        times[d] = record.time


# --- Python side ---------------------------------------------------------------------------------

_NO_ACTIONS = np.empty(0, np.int64)

class WildfireBatch:
    """A batch of episodes advanced round by round: the one home of the round logic, which
    :meth:`WildfireEnv.simulate` loops over and the vector env (:mod:`.vector`) steps.

    A round's new rows are contiguous in the log; all of them await an action, including
    decisions superseded at once (interrupted within their latency), which the dynamics never
    needed but the rollout records. So the policy reads views of the log: no gathering."""

    def __init__(self, env: WildfireEnv, draws: EpisodeDraws):
        e, n = draws.n_episodes, env.n_agents
        self.env = env
        self.holds = np.ascontiguousarray(draws.holds, np.float64)
        self.states = np.empty(e, env.state_dtype)
        self.log = np.empty(max(1024, 64 * e * n), env.log_dtype)
        self.used = np.zeros(1, np.int64)  # rows written
        self.live = np.concatenate([[e], np.arange(e)]).astype(np.int64)  # how many, then which
        self.first = 0  # the first row without an action
        _setup(self.states, self.log, self.used, env.params,
               np.ascontiguousarray(draws.starts, np.float64), np.arange(e))
        self._settle(self._advance(_NO_ACTIONS), _NO_ACTIONS)

    @property
    def n_pending(self) -> int:
        return int(self.used[0]) - self.first

    def pending(self) -> DecisionBatch:
        """The decisions awaiting an action (views of the log, valid until the next round)."""
        rows = self.log[self.first:self.used[0]]
        return DecisionBatch(obs=rows["obs"], episode=rows["ep"], agent=rows["agent"],
                             index=rows["idx"])

    def act(self, actions: np.ndarray) -> None:
        """Give every pending decision its action, and run every live episode until blocked."""
        answer = check_actions(actions, self.n_pending, self.env.n_actions, check_range=False)
        self._settle(self._advance(answer), answer)  # the range is checked in _advance

    def _advance(self, given: np.ndarray) -> int:
        status, self.first = _advance(self.states, self.live, self.log, self.used, self.env.params,
                                      self.holds, given, self.first)
        return status

    def _settle(self, status: int, answer: np.ndarray) -> None:
        """Finish a round the kernel left with ``status``: a full log grows and the round goes on
        as one (it may be a part of a large one)."""
        while status == GROW_LOG:
            self._grow()
            status = self._advance(_NO_ACTIONS)
        if status == BAD_ACTION:
            raise BadActions(answer, len(answer), self.env.n_actions)
        if status == HEAP_FULL:
            raise RuntimeError(f"event heap of {heap_capacity(self.env.cfg)} entries or queue of "
                               f"{queue_capacity(self.env.cfg)} is full")

    def _grow(self) -> None:
        bigger = np.empty(2 * len(self.log), self.log.dtype)
        bigger[:len(self.log)] = self.log
        self.log = bigger

    def restart(self, slots: np.ndarray, draws: EpisodeDraws) -> None:
        """Start the episodes of ``draws`` in the ended episodes' ``slots`` (between rounds); their
        first decisions join the pending ones."""
        while self.used[0] + len(slots) * self.env.n_agents > len(self.log):
            self._grow()
        self.holds[slots] = draws.holds
        _setup(self.states, self.log, self.used, self.env.params,
               np.ascontiguousarray(draws.starts, np.float64), slots)
        n_live = self.live[0]
        self.live[1 + n_live:1 + n_live + len(slots)] = slots
        self.live[0] = n_live + len(slots)

    def drop(self, m: int) -> None:
        """Forget the log's rows before row ``m``, which nobody reads again (the vector env has
        reported them; no running decision's row is among them): row r becomes row r - m."""
        used = int(self.used[0])
        self.log[:used - m] = self.log[m:used]
        self.used[0] = used - m
        self.first -= m
        self.states["running_row"] -= m

    def to_rollout(self) -> Rollout:
        """The recorded decisions, once every episode has ended."""
        d, rows = self.first, self.log[:self.first]
        path_start, path_episode, path_agent = path_layout(self.states["n_dec"])
        order = path_order(rows["ep"], rows["agent"], rows["idx"], self.env.n_agents, path_start)
        obs, time = np.empty((d, self.env.obs_dim)), np.empty(d)
        actions, rewards, durations = np.empty(d, np.int64), np.empty(d), np.empty(d)
        _gather(rows, order, obs, actions, rewards, durations, time)
        info = {"decision_time": time, "end_time": self.states["t_end"].copy(),
                "events": self.states["events"].copy()}
        if self.env.count_races:
            info["races"] = self.states["races"].copy()
        return Rollout(
            obs=obs, actions=actions, rewards=rewards, durations=durations, path_start=path_start,
            path_episode=path_episode, path_agent=path_agent,
            episode_return=self.states["returns"].mean(axis=1),
            truncated=self.states["truncated"].copy(), info=info)


class WildfireEnv(RunsOnStream):
    """docs/semantics.md section 3, fast: implements :class:`repro.core.rollout.BatchEnv`, and
    :class:`repro.core.rollout.RunsOnDraws` (the released pool).
    ``count_races``: each episode's races (docs/semantics.md section 3.12) in ``info["races"]``
    (an instrumentation the kernels skip otherwise)."""

    name = "wildfire"

    def __init__(self, cfg: WildfireConfig, count_races: bool = False):
        cfg.validate()
        self.cfg = cfg
        self.count_races = count_races
        self.obs_dim = cfg.obs_dim
        self.n_actions = cfg.n_actions
        self.n_agents = cfg.n_agents
        self.gamma = cfg.gamma
        self.params = params_record(cfg, count_races)
        self.state_dtype = state_dtype(cfg)
        self.log_dtype = log_dtype(cfg.obs_dim)
        self.episode_bytes = self.state_dtype.itemsize + 8 * cfg.n_agents * (2 + cfg.hold_table)
        """What a batch holds per episode besides its decisions: its state and its draws (start
        positions and hold durations), for up-front checks of sizes."""

    def rollout(self, policy: Policy, n_episodes: int,
                seed: int | np.random.SeedSequence) -> Rollout:
        return self.simulate(policy, draw_episodes(self.cfg, n_episodes, seed))

    def simulate(self, policy: Policy, draws: EpisodeDraws) -> Rollout:
        """Run the episodes of ``draws`` (tests script start positions and hold durations): one
        policy call per round."""
        batch = WildfireBatch(self, draws)
        while batch.n_pending > 0:
            batch.act(policy(batch.pending()))
        return batch.to_rollout()
