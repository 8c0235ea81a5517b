"""The fast bus engine: a numba kernel that advances a whole batch of episodes between policy calls.

It is an exact transcription of the SimPy reference (``reference.py``), event by event. SimPy keeps
a heap keyed by (time, priority, insertion id) and processes the smallest key first; this engine
schedules exactly the events SimPy schedules, in the same order, and keeps them in a small array per
episode sorted by that key, the next event last, not in the heap the other engines share
(:mod:`repro.core.event_queue` says why). Neither the priority nor the id need be stored: the only
URGENT events are the buses' initialisations, which are also inserted first, and (B5) the start of
a service process, which SimPy processes right after the event that started it, so it is folded
into that event; ordering by (time, insertion id) is therefore the same order; and a new event has
the largest id so far, so it goes just before (in processing order: just after) every event of
time <= its own.

====================  ==========================================================================
event                 SimPy counterpart, and what processing it does
====================  ==========================================================================
INIT (urgent)         ``env.process``: the bus requests Stop 1
GRANT                 ``Request.succeed``: the bus gets the stop -> arrival (headway, reward);
                      the observation, at once at its start and without B5, else two steps on
SERVED (B5)           the end of the service process: its waiting condition triggers
WAITED (B5)           the condition: the bus observes
DECISION              the driver's ``decision.succeed(action)``: alight, board, dwell + hold;
                      under B5 folded into the delivery, which schedules the latency timeout
LATENCY (B5)          the latency timeout, then (folded in) the service process starts: alight,
                      board, dwell
DWELL                 the timeout of dwell + hold (B5: of the dwell): departure, release the stop,
                      travel (B5: the hold's timeout)
HOLD (B5)             the hold's timeout: departure, release the stop, travel
RELEASE               ``Release.succeed``: grant the stop to the head of its FIFO queue
TRAVEL                the timeout of rt: request the next stop
====================  ==========================================================================

A request grants the stop at once (a GRANT event at the current time) only if nobody holds it; a
departing bus frees the stop immediately, but the next bus in the queue is granted only when the
RELEASE event is processed. Same-instant order therefore follows insertion: e.g. under No Holding
the followers reach a stop at the very instant the leader leaves it, one after the other.

Rounds: an episode runs until it is *blocked*, i.e. some bus waits for a decision and the next event
lies strictly later (all same-instant events are processed first, as they need no decision). The
policy then answers every pending decision of the whole batch in one call (rows ordered by episode,
then by the order in which the buses arrived), and each answer is scheduled as a DECISION event in
row order. Events at t >= horizon are never processed. Steps SimPy takes at the current instant
when nothing else is scheduled at it (B5: SERVED and WAITED, a zero dwell's or hold's timeout) are
taken at once, without the event: the order is the same, and they are most of No Holding's events.

Reward convention (docs/semantics.md sections 2.2, 4.4): every arrival at stop k with headway h
gives every agent r = -nu_k (h - H)^2 (B1: in pax/s and seconds, 0 if h <= 0 or at a bus's first
two visits),
added to the agent's reward buffer as exp(-gamma (t - T)) r, T the agent's discount anchor (0 at
first, then the start of its latest action: its decision, or under B5 DECISION_LATENCY later). An
agent's observation records and clears its buffer as the reward of its previous macro-action (none
before its first decision, so rewards accrued while it queues for Stop 1 go into its first
macro-action). The arrival's reward is accrued before the arriving bus observes. At the horizon
each running macro-action is cut (duration horizon - start; 0 under B5 for an action that has not
started, as the released code records it) and recorded with its buffer.

Speed. A rollout of the training batch (540 episodes) takes a few hundred rounds, so both the
per-round and the per-event costs matter. Per round, Python does O(1) work: the kernel reads the
actions in row order and gathers the next pending decisions into fresh buffers, which the policy
gets as they are (no copies). Per event, an episode's state is one numpy record (a row of a
structured array, ``episode_dtype``), and so are the parameters (``params_record``): numba hands a
record to a function as a bare pointer, whereas every array of a tuple costs a reference-count
update per call, which doubled the cost of an event. A round visits each episode's record once, so
the records are kept small (int32 fields): what is written for the rollout lives in a separate
record per episode (``log_dtype``, 25 times the size) and is never read back by the kernel. Those
writes miss the cache, so they are as few as can be: one 64-byte row per macro-action, written when
it closes (its observation with h in seconds, action, reward, duration and observation time), and
the bus of each observation; every stop visit starts a macro-action, whose row holds the rest of
the visit's record (``arrivals`` recomputes U and B with the function that boarded them). A stop's
FIFO queue is the waiting buses ordered by request ticket, a scan over N buses instead of a ring
buffer per stop.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
import numpy as np
from numba import njit

from repro.core.config import numba_record
from repro.core.errors import require
from repro.core.paths import path_layout
from repro.core.rollout import BadActions, DecisionBatch, Rollout, RunsToEnd, check_actions
from repro.envs.bus.params import DECISION_LATENCY, OBS_DIM, BusConfig

INIT, GRANT, DECISION, DWELL, RELEASE, TRAVEL, HOLD, SERVED, WAITED, LATENCY = range(10)
"""Event kinds (see the table above)."""

D_ACTION, D_REWARD, D_DURATION, D_TIME = range(OBS_DIM, OBS_DIM + 4)
"""Fields of a ``dec`` row after the observation [stop, h (s), load, sojourn]; D_TIME is the
observation's time."""
EPISODE, AGENT, INDEX = range(3)
"""Rows of the pending decisions' ``ids`` buffer."""

jit = njit(cache=True)


def params_record(cfg: BusConfig) -> np.ndarray:
    """The (1,) structured array of the kernels' parameters: the config's fields by name
    (:func:`repro.core.config.numba_record`), then the arrival rates per second, the planned
    headway in seconds, and the decision latency."""
    return numba_record(cfg, rate_s=np.array(cfg.arrival_rate, float) / 60.0,
                        headway_s=60.0 * cfg.headway, decision_latency=DECISION_LATENCY)


def episode_dtype(cfg: BusConfig) -> np.dtype:
    """One episode's hot state: scalars, the event list, (N,) bus fields, (K,) stop fields."""
    n, k, f8, i4 = cfg.n_buses, cfg.n_stops, np.float64, np.int32  # int32: small records
    cap = 2 * n  # scheduled at once: one event of each bus, plus the RELEASE of the stop it left
    return np.dtype([
        # the episode: time, undiscounted return, queue tickets handed out, arrivals so far, and
        # the buses waiting for a decision, in arrival order
        ("now", f8), ("ret", f8), ("done", np.bool_), ("next_ticket", i4), ("n_arr", i4),
        ("n_pending", i4), ("pending", i4, n),
        # the event list: n_ev events in slots 0..n_ev-1, last to be processed first; time, kind,
        # bus or stop
        ("n_ev", i4), ("ev_time", f8, cap), ("ev_kind", i4, cap), ("ev_arg", i4, cap),
        # buses: discount anchor T (start of the running action), reward buffer, the running
        # macro-action's observation (h in seconds) and action, its observation time, whether its
        # action has started, the headway (s) of its latest arrival, stop, load, decisions (= stop
        # visits) so far, request ticket while queued (else -1)
        ("anchor", f8, n), ("buffer", f8, n), ("obs", f8, (n, OBS_DIM)), ("action", i4, n),
        ("t_obs", f8, n), ("started", np.int8, n), ("h", f8, n), ("stop", i4, n), ("load", i4, n),
        ("n_dec", i4, n), ("ticket", i4, n),
        # stops: last departure time (-1: none yet), 1 while a bus holds the stop
        ("departed", f8, k), ("busy", np.int8, k),
    ], align=True)


def log_dtype(cfg: BusConfig) -> np.dtype:
    """One episode's records: each bus's closed macro-actions, one 64-byte float row each (the
    integers in it are small, hence exact): observation (h in seconds), D_ACTION, D_REWARD,
    D_DURATION and D_TIME, the time of the stop visit that started it; and the bus of each
    observation, in processing order. Every stop visit starts a macro-action, so this is the whole
    visit record (see ``arrivals``)."""
    n, m = cfg.n_buses, cfg.max_arrivals_per_bus
    return np.dtype([("dec", np.float64, (n, m, OBS_DIM + 4)), ("order", np.int32, n * m)],
                    align=True)


@jit
def _schedule(state, t, kind, arg):
    """Insert an event behind every event of time <= t (it has the largest insertion id)."""
    i = state.n_ev
    if i == state.ev_time.shape[0]:
        raise RuntimeError("bus engine: more than 2 N events scheduled at once")
    while i > 0 and state.ev_time[i - 1] <= t:
        state.ev_time[i] = state.ev_time[i - 1]
        state.ev_kind[i] = state.ev_kind[i - 1]
        state.ev_arg[i] = state.ev_arg[i - 1]
        i -= 1
    state.ev_time[i] = t
    state.ev_kind[i] = kind
    state.ev_arg[i] = arg
    state.n_ev += 1


@jit
def _grant_stop(state, k, t):
    """If stop k is free, grant it to the bus that requested it first (a GRANT event at t)."""
    if state.busy[k]:
        return
    first = -1
    for b in range(state.stop.shape[0]):
        if (state.ticket[b] >= 0 and state.stop[b] == k
                and (first < 0 or state.ticket[b] < state.ticket[first])):
            first = b
    if first >= 0:
        state.ticket[first] = -1
        state.busy[k] = 1
        _schedule(state, t, GRANT, first)


@jit
def _headway(params, state, b, t):
    """h (s) of bus b getting its stop at t (-1: unknown, under B2). Buses cannot overtake (FIFO
    stops, one travel time for all), so the latest departure from the stop is that of the bus
    ahead, B2's reference, whenever that bus has left the stop in this lap."""
    dep = state.departed[state.stop[b]]
    if not params.b2_headway:
        return t - max(dep, 0.0)  # the episode start if nobody has left yet
    if state.n_dec[b] == 0 or dep < 0.0:
        return -1.0
    return t - dep


@jit
def _reward(params, k, h, visit):
    """The reward of an arrival at stop k with headway h (s) at the bus's visit-th stop visit."""
    if not params.b1_reward:
        d = h / 60.0 - params.headway
        return -params.arrival_rate[k] * (d * d)  # as the reference: the correctly rounded square
    if h <= 0.0 or visit <= 2:
        return 0.0
    d = h - params.headway_s
    return -params.rate_s[k] * (d * d)


@jit
def _arrive(params, state, log, b, t):
    """Bus b gets its stop: headway, reward every agent; observe now, or (B5, after the first visit)
    two same-instant steps later, when the released bus's service process and its wait end."""
    k = state.stop[b]
    h = _headway(params, state, b, t)
    state.h[b] = h
    reward = _reward(params, k, h, state.n_dec[b] + 1)
    state.ret += reward
    for j in range(state.buffer.shape[0]):
        state.buffer[j] += np.exp(-params.gamma * (t - state.anchor[j])) * reward
    if params.b5_timing and state.n_dec[b] > 0 and not _alone_at(state, t):
        _schedule(state, t, SERVED, b)
    else:
        _observe(params, state, log, b, t)


@jit
def _observe(params, state, log, b, t):
    """Bus b observes: close its previous macro-action, await a decision."""
    log.order[state.n_arr] = b
    state.n_arr += 1
    n = state.n_dec[b]
    if n > 0:
        _close(state, log, b, t)
    state.obs[b, 0] = state.stop[b]
    state.obs[b, 1] = state.h[b]
    state.obs[b, 2] = state.load[b]
    state.obs[b, 3] = t - state.anchor[b]
    state.t_obs[b] = t
    if not params.b5_timing:
        state.anchor[b] = t
    state.started[b] = 0
    state.n_dec[b] = n + 1
    state.pending[state.n_pending] = b
    state.n_pending += 1


@jit
def _close(state, log, b, t):
    """Record bus b's running macro-action, ending at t, and empty its reward buffer."""
    row = log.dec[b, state.n_dec[b] - 1]
    for i in range(OBS_DIM):
        row[i] = state.obs[b, i]
    row[D_ACTION] = state.action[b]
    row[D_REWARD] = state.buffer[b]
    row[D_DURATION] = t - state.anchor[b]
    row[D_TIME] = state.t_obs[b]
    state.buffer[b] = 0.0


@jit
def _h_obs(params, h):
    """The observed headway: seconds under B2, else minutes."""
    return h if params.b2_headway else h / 60.0


@jit
def _round(params, x):
    return np.int64(np.rint(x) if params.b4_round_half_even else np.floor(x + 0.5))


@jit
def _alight_board(params, k, load, h, visit, t):
    """Passengers alighting U and boarding B at stop k, given the load and headway h (s) at the
    bus's visit-th stop visit, its service starting at t."""
    u = _round(params, params.alight_fraction[k] * load)
    if params.b3_boarding:
        bd = _round(params, params.rate_s[k] * (h if visit > 2 else t))
    else:
        bd = _round(params, params.arrival_rate[k] * (h / 60.0))
    return u, min(bd, params.l_max - (load - u))


@jit
def _serve(params, state, b, t):
    """The action starts: alight, board, and dwell plus hold (a DWELL event; under B5 the hold is
    a timeout of its own after the dwell's)."""
    if params.b5_timing:
        state.anchor[b] = t
    state.started[b] = 1
    load = state.load[b]
    u, bd = _alight_board(params, state.stop[b], load, state.h[b], state.n_dec[b], t)
    state.load[b] = load - u + bd
    dwell = max(params.t_alight * u, params.t_board * bd)
    if params.b5_timing:
        if dwell == 0.0 and _alone_at(state, t):
            _hold(params, state, b, t)
        else:
            _schedule(state, t + dwell, DWELL, b)
    else:
        _schedule(state, t + (dwell + state.action[b] * params.t_hold), DWELL, b)


@jit
def _alone_at(state, t):
    """No event is scheduled at t (the current time): an event scheduled now at t would be the
    next one processed, so it may be processed at once (same order, fewer steps)."""
    return state.n_ev == 0 or state.ev_time[state.n_ev - 1] > t


@jit
def _hold(params, state, b, t):
    """B5: the dwell's timeout is over; the hold's timeout (HOLD), or leave at once if it is 0."""
    hold = state.action[b] * params.t_hold
    if hold == 0.0 and _alone_at(state, t):
        _depart(params, state, b, t)
    else:
        _schedule(state, t + hold, HOLD, b)


@jit
def _depart(params, state, b, t):
    """Leave the stop, free it, travel on."""
    k = state.stop[b]
    state.departed[k] = t
    state.busy[k] = 0
    _schedule(state, t, RELEASE, k)
    _schedule(state, t + params.travel_time, TRAVEL, b)


@jit
def _end_episode(params, state, log):
    """Cut every running macro-action at the horizon (one whose action has not started yet, under
    B5, lasts 0 s, as in the released code)."""
    state.done = True
    for b in range(state.n_dec.shape[0]):
        if state.n_dec[b] > 0:
            _close(state, log, b, params.horizon if state.started[b] else state.anchor[b])


@jit
def _run_episode(params, state, log):
    """Process the episode's events until it is blocked on decisions or reaches the horizon."""
    n_stop = state.busy.shape[0]
    while True:
        t = state.ev_time[state.n_ev - 1] if state.n_ev > 0 else np.inf
        if state.n_pending > 0 and t > state.now:
            return  # blocked on decisions
        if t >= params.horizon:  # includes inf: nothing scheduled
            _end_episode(params, state, log)
            return
        state.n_ev -= 1
        kind = state.ev_kind[state.n_ev]
        arg = state.ev_arg[state.n_ev]
        state.now = t
        if kind == INIT or kind == TRAVEL:  # request a stop (the next one after a trip)
            if kind == TRAVEL:
                state.stop[arg] = (state.stop[arg] + 1) % n_stop
            state.ticket[arg] = state.next_ticket
            state.next_ticket += 1
            _grant_stop(state, state.stop[arg], t)  # a request triggers the queue at once
        elif kind == RELEASE:
            _grant_stop(state, arg, t)
        elif kind == GRANT:
            _arrive(params, state, log, arg, t)
        elif kind == SERVED:
            _schedule(state, t, WAITED, arg)
        elif kind == WAITED:
            _observe(params, state, log, arg, t)
        elif kind == DECISION or kind == LATENCY:
            _serve(params, state, arg, t)
        elif kind == DWELL and params.b5_timing:
            _hold(params, state, arg, t)
        else:  # DWELL without B5, HOLD: depart
            _depart(params, state, arg, t)


@jit
def _advance(actions, params_array, states, logs, obs, ids):
    """Deliver the actions of the pending decisions, run every episode until it is blocked, and
    gather the new pending decisions into the first rows of ``obs`` and ``ids``.

    ``actions`` answer the previous round's rows in order (episode, then arrival order). Returns the
    number of new rows, or -1 if an action is out of range (nothing is changed then).
    """
    params = params_array[0]
    for i in range(actions.shape[0]):
        if actions[i] < 0 or actions[i] >= params.n_actions:
            return -1
    row = 0
    rows = 0
    for e in range(states.shape[0]):
        state = states[e]
        if state.done:
            continue
        for q in range(state.n_pending):
            b = state.pending[q]
            state.action[b] = actions[row]
            row += 1
            # B5: the DECISION events would be the instant's last, each scheduling its latency
            # timeout and nothing else; so the timeouts are scheduled at once, in the same order
            if params.b5_timing:
                _schedule(state, state.now + params.decision_latency, LATENCY, b)
            else:
                _schedule(state, state.now, DECISION, b)
        state.n_pending = 0
        _run_episode(params, state, logs[e])
        rows = _gather(params, state, e, obs, ids, rows)
    return rows


@jit
def _gather(params, state, e, obs, ids, rows):
    """Episode e's pending decisions into rows ``rows``, ... of ``obs`` and ``ids``; returns the
    next free row."""
    for q in range(state.n_pending):
        b = state.pending[q]
        for i in range(OBS_DIM):
            obs[rows, i] = state.obs[b, i]
        obs[rows, 1] = _h_obs(params, state.obs[b, 1])
        ids[EPISODE, rows] = e
        ids[AGENT, rows] = b
        ids[INDEX, rows] = state.n_dec[b] - 1
        rows += 1
    return rows


@jit
def _start(params_array, states, logs, slots, obs, ids):
    """Run the (freshly initialised) episodes ``slots`` until they are blocked, then gather the
    pending decisions of every episode, in episode order as ``_advance`` does. Returns the number
    of rows."""
    params = params_array[0]
    for e in slots:
        _run_episode(params, states[e], logs[e])
    rows = 0
    for e in range(states.shape[0]):
        rows = _gather(params, states[e], e, obs, ids, rows)
    return rows


class BusBatch:
    """A batch of episodes advanced round by round (see the module docstring)."""

    def __init__(self, cfg: BusConfig, n_episodes: int):
        require(n_episodes >= 1, "n_episodes", "an integer >= 1", n_episodes)
        self.cfg = cfg
        self._params = params_record(cfg)
        self._states = np.zeros(n_episodes, episode_dtype(cfg))
        self._initialise(np.arange(n_episodes))
        self._logs = np.empty(n_episodes, log_dtype(cfg))  # every row read back is written first
        self._decisions = _gathered(np.empty((0, OBS_DIM)), np.empty((3, 0), np.int64), 0)

    def _initialise(self, slots: np.ndarray) -> None:
        """The states of episodes ``slots`` at time 0, before any event."""
        n, st = self.cfg.n_buses, self._states
        st[slots] = np.zeros(1, st.dtype)
        st["ticket"][slots] = -1
        st["departed"][slots] = -1.0
        # SimPy starts one process per bus with an URGENT initialisation event, in bus order.
        st["n_ev"][slots] = n
        st["ev_kind"][slots, :n] = INIT
        st["ev_arg"][slots, :n] = np.arange(n)[::-1]  # bus 0's last: processed from the end

    def restart(self, slots: np.ndarray) -> DecisionBatch:
        """Start the ended episodes ``slots`` again from time 0 (the environment is
        deterministic: every episode is the same) and run them until blocked; the pending
        decisions of the batch, theirs included (only between rounds: the others' are
        unchanged)."""
        require(bool(self._states["done"][slots].all()), "restart", "of ended episodes", slots)
        self._initialise(slots)
        obs, ids = self._buffers()
        rows = _start(self._params, self._states, self._logs, np.asarray(slots, np.int64), obs, ids)
        self._decisions = _gathered(obs, ids, rows)
        return self._decisions

    def _buffers(self) -> tuple[np.ndarray, np.ndarray]:
        """Fresh buffers for a round's pending decisions, handed to the policy as they are (it may
        keep them): one row per bus of the batch at most."""
        size = self._states.shape[0] * self.cfg.n_buses
        return np.empty((size, OBS_DIM)), np.empty((3, size), np.int64)

    @property
    def done(self) -> np.ndarray:
        """(E,) bool: the episode has reached the horizon."""
        return self._states["done"].copy()

    @property
    def ep_return(self) -> np.ndarray:
        """(E,) the undiscounted return so far (sum of every arrival's reward)."""
        return self._states["ret"].copy()

    def advance(self, actions: np.ndarray) -> DecisionBatch:
        """Answer the pending decisions (one action per row of the last batch), run until blocked,
        and return the new pending decisions (empty once every episode has ended)."""
        actions = check_actions(actions, len(self._decisions), self.cfg.n_actions,
                                check_range=False)
        obs, ids = self._buffers()
        rows = _advance(actions, self._params, self._states, self._logs, obs, ids)
        if rows < 0:  # an action out of range, found in the kernel
            raise BadActions(actions, len(actions), self.cfg.n_actions)
        self._decisions = _gathered(obs, ids, rows)
        return self._decisions

    def state(self, e: int) -> np.void:
        """Episode e's state record (a copy), for pictures."""
        return self._states[e].copy()

    @property
    def n_decisions(self) -> np.ndarray:
        """(E, N) decisions so far of every bus of every episode."""
        return self._states["n_dec"].astype(np.int64)

    def macro_actions(self, episode: np.ndarray, agent: np.ndarray,
                      index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The reward and duration of closed macro-actions (one per element of the arguments)."""
        rows = self._logs["dec"][episode, agent, index]
        return rows[:, D_REWARD], rows[:, D_DURATION]

    def ended(self, was_over: np.ndarray) -> tuple[np.ndarray, ...]:
        """The macro-actions the last :meth:`advance` ended, given which episodes were over
        before it: each pending decision's bus's previous one (a bus observes again when its
        macro-action ends), in the pending rows' order, then every bus's last one in the episodes
        that reached the horizon in it, in (episode, bus) order. Columns (episode, agent, index,
        reward, duration, last): ``last`` marks those the horizon cut."""
        d, e = self._decisions, len(self._states)
        n = len(d) + e * self.cfg.n_buses
        ids, values, last = np.empty((3, n), np.int64), np.empty((2, n)), np.empty(n, np.bool_)
        m = _ended(self._states, self._logs, d.episode, d.agent, d.index,
                   np.ascontiguousarray(was_over, np.bool_), ids, values, last)
        return ids[0, :m], ids[1, :m], ids[2, :m], values[0, :m], values[1, :m], last[:m]

    def decisions(self) -> DecisionBatch:
        """The pending decisions (those the last :meth:`advance` returned)."""
        return self._decisions

    def arrivals(self) -> dict[str, np.ndarray]:
        """Every served stop visit of every episode (a bus's start at Stop 1 included), in the
        order of the observations: episode, time (s) of the arrival, bus, stop (0-based), h (min;
        NaN where B2 has none), load at arrival, alighting U and boarding B."""
        require(bool(self.done.all()), "arrivals", "taken after every episode has ended")
        d = int(self._states["n_arr"].sum())
        time, h = np.empty(d), np.empty(d)
        episode, bus, stop, load, alight, board = np.empty((6, d), np.int64)
        d = _arrivals(self._params, self._states, self._logs, episode, time, bus, stop, h, load,
                      alight, board)
        return dict(episode=episode[:d], time=time[:d], bus=bus[:d], stop=stop[:d], h=h[:d],
                    load=load[:d], alight=alight[:d], board=board[:d])

    def to_rollout(self) -> Rollout:
        require(bool(self.done.all()), "rollout", "taken after every episode has ended")
        n_dec = self._states["n_dec"]
        path_start, path_episode, path_agent = path_layout(n_dec)
        d = int(path_start[-1])
        obs, rewards, durations = np.empty((d, OBS_DIM)), np.empty(d), np.empty(d)
        actions = np.empty(d, np.int64)
        _decisions(self._params, self._logs, n_dec, obs, actions, rewards, durations)
        return Rollout(
            obs=obs, actions=actions, rewards=rewards, durations=durations,
            path_start=path_start, path_episode=path_episode, path_agent=path_agent,
            episode_return=self.ep_return, info={"arrivals": _OnFirstUse(self.arrivals)})


class _OnFirstUse(Mapping[str, np.ndarray]):
    """A table made on first use: only evaluation and the figures read a rollout's arrival table,
    and making it would add about 5% to every training rollout."""

    def __init__(self, make: Callable[[], dict[str, np.ndarray]]):
        self._make: Callable[[], dict[str, np.ndarray]] | None = make
        self._table: dict[str, np.ndarray] = {}

    def _made(self) -> dict[str, np.ndarray]:
        if self._make is not None:
            self._table, self._make = self._make(), None
        return self._table

    def __getitem__(self, key: str) -> np.ndarray:
        return self._made()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._made())

    def __len__(self) -> int:
        return len(self._made())


def _gathered(obs: np.ndarray, ids: np.ndarray, rows: int) -> DecisionBatch:
    """The first ``rows`` rows of the decision buffers, as views."""
    return DecisionBatch(obs=obs[:rows], episode=ids[EPISODE, :rows], agent=ids[AGENT, :rows],
                         index=ids[INDEX, :rows])


@jit
def _decisions(params_array, logs, n_dec, obs, actions, rewards, durations):
    """Every closed macro-action's row into the rollout's columns, path by path (a compiled loop:
    numpy's boolean-mask indexing took a quarter of a rollout)."""
    params = params_array[0]
    o = 0
    for e in range(logs.shape[0]):
        dec = logs[e].dec
        for b in range(n_dec.shape[1]):
            for i in range(n_dec[e, b]):
                row = dec[b, i]
                for w in range(OBS_DIM):
                    obs[o, w] = row[w]
                obs[o, 1] = _h_obs(params, row[1])
                actions[o] = np.int64(row[D_ACTION])
                rewards[o] = row[D_REWARD]
                durations[o] = row[D_DURATION]
                o += 1


@jit
def _ended(states, logs, episode, agent, index, was_over, ids, values, last):
    """:meth:`BusBatch.ended`'s rows into the columns of ``ids`` (episode, agent, index),
    ``values`` (reward, duration) and ``last``; returns their number."""
    m = 0
    for r in range(len(episode)):
        if index[r] > 0:
            ids[0, m], ids[1, m], ids[2, m] = episode[r], agent[r], index[r] - 1
            row = logs[episode[r]].dec[agent[r], index[r] - 1]
            values[0, m], values[1, m], last[m] = row[D_REWARD], row[D_DURATION], False
            m += 1
    for e in range(states.shape[0]):
        state = states[e]
        if not state.done or was_over[e]:
            continue
        for b in range(state.n_dec.shape[0]):
            if state.n_dec[b] > 0:
                ids[0, m], ids[1, m], ids[2, m] = e, b, state.n_dec[b] - 1
                row = logs[e].dec[b, state.n_dec[b] - 1]
                values[0, m], values[1, m], last[m] = row[D_REWARD], row[D_DURATION], True
                m += 1
    return m


@jit
def _arrivals(params_array, states, logs, episode, time, bus, stop, h, load, alight, board):
    """Every served visit's fields, from the macro-action its observation started (the bus's next
    one, in order), into the rows of the arrival table's columns (see ``BusBatch.arrivals``; U
    and B as ``_serve`` computed them). A last decision whose action never started (B5, at the
    horizon) served nobody: left out. Returns the number of rows."""
    params = params_array[0]
    o = 0
    for e in range(logs.shape[0]):
        log, state = logs[e], states[e]
        seen = np.zeros(log.dec.shape[0], np.int64)
        for i in range(state.n_arr):
            b = log.order[i]
            row = log.dec[b, seen[b]]
            seen[b] += 1
            if seen[b] == state.n_dec[b] and not state.started[b]:
                continue
            k, load_at_arrival, h_s = np.int64(row[0]), np.int64(row[2]), row[1]
            episode[o] = e
            time[o] = row[D_TIME]
            bus[o] = b
            stop[o] = k
            h[o] = np.nan if params.b2_headway and h_s == -1.0 else h_s / 60.0
            load[o] = load_at_arrival
            start = row[D_TIME] + params.decision_latency if params.b5_timing else row[D_TIME]
            alight[o], board[o] = _alight_board(params, k, load_at_arrival, h_s, seen[b], start)
            o += 1
    return o


class BusEnv(RunsToEnd):
    """The fast engine as a :class:`repro.core.rollout.BatchEnv`."""

    name = "bus"
    obs_dim = OBS_DIM

    def __init__(self, cfg: BusConfig | None = None):
        self.cfg = cfg or BusConfig()
        self.n_actions = self.cfg.n_actions
        self.n_agents = self.cfg.n_buses
        self.gamma = self.cfg.gamma
        self.episode_bytes = episode_dtype(self.cfg).itemsize
        """What a batch holds per episode besides its decisions (its state), for up-front checks
        of sizes."""

    def start(self, n_episodes: int) -> BusBatch:
        return BusBatch(self.cfg, n_episodes)
