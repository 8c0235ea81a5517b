"""The fast bus engine: a numba kernel that advances a whole batch of episodes between policy calls.

It is an exact transcription of the SimPy reference (``reference.py``), event by event. SimPy keeps
a heap keyed by (time, priority, insertion id) and processes the smallest key first; this engine
keeps the same keys in a small array per episode (at most 2 N events are ever scheduled, so a
linear scan for the minimum beats a heap) and schedules exactly the events SimPy schedules, in the
same order. The priority need not be stored: the only URGENT events are the buses' initialisations,
which are also inserted first, so ordering by (time, insertion id) is the same order.

====================  ==========================================================================
event                 SimPy counterpart, and what processing it does
====================  ==========================================================================
INIT (urgent)         ``env.process``: the bus requests Stop 1
GRANT                 ``Request.succeed``: the bus gets the stop -> arrival (reward, observation)
DECISION              the driver's ``decision.succeed(action)``: alight, board, dwell + hold
DWELL                 the timeout of dwell + hold: departure, release the stop, travel
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
row order. Events at t >= horizon are never processed.

Reward convention (SPEC 5.2 and section 3): every arrival at stop k with headway h gives every agent
r = -nu_k (h - H)^2, added to the agent's reward buffer as exp(-gamma (t - T)) r, T the agent's
discount anchor (0 at first, then the time of its latest decision). An agent's observation records
and clears its buffer as the reward of its previous macro-action (none before its first decision,
so rewards accrued while it queues for Stop 1 go into its first macro-action). The arrival's reward
is accrued before the arriving bus observes. At the horizon each running macro-action is cut
(duration horizon - start) and recorded with its buffer.

Speed. A rollout of the training batch (540 episodes) takes a few hundred rounds, so both the
per-round and the per-event costs matter. Per round, Python does O(1) work: the kernel takes four
tuples of arrays (numba's dispatch costs about a microsecond per array), reads the actions in row
order and gathers the next pending decisions into preallocated buffers. Per event, the state an
episode touches is contiguous (one row per episode in each array below, fields last), so a round
visits each episode's few cache lines once, and the records are written once per row (a decision's
row when its macro-action closes, an arrival's when the bus boards), never read back, so the state
a round touches stays small; a stop's FIFO queue is the waiting buses ordered by request ticket, a
scan over N buses instead of a ring buffer per stop; the kernels run without reference counting
(``_kernel``).

Packed state (``_State``; the field constants below name the last axis):

=================  =============  =================================================================
array              shape          fields
=================  =============  =================================================================
``ep_real``        (E, 2)         NOW, RETURN (the undiscounted episode return)
``ep_int``         (E, 5 + N)     DONE, NEXT_ID (insertion ids), NEXT_TICKET (queue order), N_ARR,
                                  N_PENDING, then the buses waiting for a decision, in arrival order
``ev_time``        (E, 2 N)       event time; inf marks a free slot
``ev_int``         (E, 2 N, 3)    ID (insertion id), KIND, ARG (bus or stop)
``bus_real``       (E, N, 6)      ANCHOR (discount anchor T), BUFFER (reward buffer), then OBS: the
                                  observation of the running macro-action
``bus_int``        (E, N, 6)      STOP, LOAD, N_DEC (decisions so far), ARRIVAL (index of the latest
                                  arrival), TICKET (request ticket while queued, else -1), ACTION (of
                                  the running macro-action)
``stop_real``      (E, K)         last departure time
``stop_busy``      (E, K)         1 while a bus holds the stop
=================  =============  =================================================================
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numba as nb
import numpy as np

from repro.core.errors import UsageError, require
from repro.core.rollout import DecisionBatch, Policy, Rollout
from repro.envs.bus.params import BusConfig

OBS_DIM = 4
"""Observation: [stop index (0-based), headway h (min), load at arrival (pax), sojourn time (s)]."""

INIT, GRANT, DECISION, DWELL, RELEASE, TRAVEL = range(6)
"""Event kinds (see the table above)."""

# Fields (last axis) of the packed state, the records and the decision buffers; see the tables.
NOW, RETURN = range(2)
DONE, NEXT_ID, NEXT_TICKET, N_ARR, N_PENDING, PENDING = range(6)
ID, KIND, ARG = range(3)
ANCHOR, BUFFER, OBS = range(3)  # OBS: the first of OBS_DIM fields
STOP, LOAD, N_DEC, ARRIVAL, TICKET, ACTION = range(6)
D_ACTION, D_REWARD, D_DURATION = range(OBS_DIM, OBS_DIM + 3)  # after the observation
TIME, HEADWAY, A_BUS, A_STOP, A_LOAD, A_ALIGHT, A_BOARD = range(7)
EPISODE, AGENT, INDEX = range(3)


_kernel = nb.njit(cache=True, _nrt=False)
"""How the engine's functions are compiled. They allocate nothing (every array is made once, in
:class:`BusBatch`), so they run without numba's reference-counting runtime: with it, each array a
call passes or a tuple field it reads is counted atomically, which doubled the cost of an event."""


class _Params(NamedTuple):
    """The configuration as the kernel reads it (fixed types, so the compiled kernel is reused)."""

    n_actions: int
    alight: np.ndarray
    rate: np.ndarray
    l_max: int
    rt: float
    t_a: float
    t_b: float
    headway: float
    t_hold: float
    gamma: float
    horizon: float


class _State(NamedTuple):
    """The simulation state of every episode (module docstring, "Packed state")."""

    ep_real: np.ndarray
    ep_int: np.ndarray
    ev_time: np.ndarray
    ev_int: np.ndarray
    bus_real: np.ndarray
    bus_int: np.ndarray
    stop_real: np.ndarray
    stop_busy: np.ndarray


class _Record(NamedTuple):
    """What the episodes have produced so far, one float row per item (the integers in them are
    small, hence exact): a row is written whole, once, which keeps the writes cache-friendly."""

    dec: np.ndarray
    """(E, N, M, OBS_DIM + 3): each closed macro-action's observation, D_ACTION, D_REWARD and
    D_DURATION."""
    arr: np.ndarray
    """(E, N M, 7): each arrival's TIME (s), HEADWAY h (min), A_BUS, A_STOP, A_LOAD (at arrival),
    A_ALIGHT U and A_BOARD B."""


class _Pending(NamedTuple):
    """Preallocated buffers the kernel gathers the pending decisions into (the first rows)."""

    obs: np.ndarray
    """(E N, OBS_DIM)."""
    ids: np.ndarray
    """(3, E N): EPISODE, AGENT, INDEX of each row."""


@_kernel
def _schedule(ev_time, ev_int, ep_int, e, t, kind, arg):
    """Schedule an event of episode e in a free slot, with the next insertion id."""
    for s in range(ev_time.shape[1]):
        if ev_time[e, s] == np.inf:
            ev_time[e, s] = t
            ev_int[e, s, ID] = ep_int[e, NEXT_ID]
            ev_int[e, s, KIND] = kind
            ev_int[e, s, ARG] = arg
            ep_int[e, NEXT_ID] += 1
            return
    raise RuntimeError("bus engine: more than 2 N events scheduled at once")


@_kernel
def _next_event(ev_time, ev_int, e):
    """Slot of the smallest (time, id) key; its time is inf when nothing is scheduled."""
    best = 0
    for s in range(1, ev_time.shape[1]):
        if ev_time[e, s] < ev_time[e, best] or (
                ev_time[e, s] == ev_time[e, best] and ev_int[e, s, ID] < ev_int[e, best, ID]):
            best = s
    return best


@_kernel
def _grant_stop(state, e, k, t):
    """If stop k is free, grant it to the bus that requested it first (a GRANT event at t)."""
    if state.stop_busy[e, k]:
        return
    bus_int = state.bus_int
    first = -1
    for b in range(bus_int.shape[1]):
        if bus_int[e, b, TICKET] >= 0 and bus_int[e, b, STOP] == k and (
                first < 0 or bus_int[e, b, TICKET] < bus_int[e, first, TICKET]):
            first = b
    if first >= 0:
        bus_int[e, first, TICKET] = -1
        state.stop_busy[e, k] = 1
        _schedule(state.ev_time, state.ev_int, state.ep_int, e, t, GRANT, first)


@_kernel
def _arrive(par, state, rec, e, b, t):
    """Bus b gets its stop: reward every agent, record the arrival, observe, await a decision."""
    ep_int, bus_real, bus_int = state.ep_int, state.bus_real, state.bus_int
    k = bus_int[e, b, STOP]
    h = (t - state.stop_real[e, k]) / 60.0
    d = h - par.headway
    r = -par.rate[k] * (d * d)  # as the reference: the correctly rounded square
    state.ep_real[e, RETURN] += r
    for j in range(bus_real.shape[1]):
        bus_real[e, j, BUFFER] += np.exp(-par.gamma * (t - bus_real[e, j, ANCHOR])) * r
    bus_int[e, b, ARRIVAL] = ep_int[e, N_ARR]  # its row is written when the bus boards
    ep_int[e, N_ARR] += 1
    n = bus_int[e, b, N_DEC]
    if n > 0:  # the observation closes the previous macro-action
        _close(rec, bus_real, bus_int, e, b, t)
    bus_real[e, b, OBS] = k
    bus_real[e, b, OBS + 1] = h
    bus_real[e, b, OBS + 2] = bus_int[e, b, LOAD]
    bus_real[e, b, OBS + 3] = t - bus_real[e, b, ANCHOR]
    bus_real[e, b, ANCHOR] = t
    bus_int[e, b, N_DEC] = n + 1
    ep_int[e, PENDING + ep_int[e, N_PENDING]] = b
    ep_int[e, N_PENDING] += 1


@_kernel
def _close(rec, bus_real, bus_int, e, b, t):
    """Record bus b's running macro-action, ending at t, and empty its reward buffer."""
    row = rec.dec[e, b, bus_int[e, b, N_DEC] - 1]
    for i in range(OBS_DIM):
        row[i] = bus_real[e, b, OBS + i]
    row[D_ACTION] = bus_int[e, b, ACTION]
    row[D_REWARD] = bus_real[e, b, BUFFER]
    row[D_DURATION] = t - bus_real[e, b, ANCHOR]
    bus_real[e, b, BUFFER] = 0.0


@_kernel
def _board(par, state, rec, e, b, t):
    """The decision is in: alight, board, record the arrival, and dwell plus hold (a DWELL event)."""
    bus_real, bus_int = state.bus_real, state.bus_int
    k = bus_int[e, b, STOP]
    h = bus_real[e, b, OBS + 1]
    load = bus_int[e, b, LOAD]
    u = np.int64(np.floor(par.alight[k] * load + 0.5))
    bd = min(np.int64(np.floor(par.rate[k] * h + 0.5)), par.l_max - load + u)
    bus_int[e, b, LOAD] = load - u + bd
    row = rec.arr[e, bus_int[e, b, ARRIVAL]]
    row[TIME] = bus_real[e, b, ANCHOR]  # the arrival's time
    row[HEADWAY] = h
    row[A_BUS] = b
    row[A_STOP] = k
    row[A_LOAD] = load
    row[A_ALIGHT] = u
    row[A_BOARD] = bd
    _schedule(state.ev_time, state.ev_int, state.ep_int, e,
              t + (max(par.t_a * u, par.t_b * bd) + bus_int[e, b, ACTION] * par.t_hold), DWELL, b)


@_kernel
def _end_episode(par, state, rec, e):
    """Cut every running macro-action at the horizon."""
    state.ep_int[e, DONE] = 1
    for b in range(state.bus_int.shape[1]):
        if state.bus_int[e, b, N_DEC] > 0:
            _close(rec, state.bus_real, state.bus_int, e, b, par.horizon)


# inlined into _advance: a call would push each array of the tuples on the stack, field by field
@nb.njit(cache=True, _nrt=False, inline="always")
def _run_episode(par, state, rec, e):
    """Process episode e's events until it is blocked on decisions or reaches the horizon."""
    ep_int, ev_time, ev_int, bus_int = state.ep_int, state.ev_time, state.ev_int, state.bus_int
    n_stop = state.stop_busy.shape[1]
    while True:
        s = _next_event(ev_time, ev_int, e)
        t = ev_time[e, s]
        if ep_int[e, N_PENDING] > 0 and t > state.ep_real[e, NOW]:
            return  # blocked on decisions
        if t >= par.horizon:  # includes inf: nothing scheduled
            _end_episode(par, state, rec, e)
            return
        kind = ev_int[e, s, KIND]
        arg = ev_int[e, s, ARG]
        ev_time[e, s] = np.inf
        state.ep_real[e, NOW] = t
        if kind == INIT or kind == TRAVEL:  # request a stop (the next one after a trip)
            if kind == TRAVEL:
                bus_int[e, arg, STOP] = (bus_int[e, arg, STOP] + 1) % n_stop
            bus_int[e, arg, TICKET] = ep_int[e, NEXT_TICKET]
            ep_int[e, NEXT_TICKET] += 1
            _grant_stop(state, e, bus_int[e, arg, STOP], t)  # a request triggers the queue at once
        elif kind == RELEASE:
            _grant_stop(state, e, arg, t)
        elif kind == GRANT:
            _arrive(par, state, rec, e, arg, t)
        elif kind == DECISION:
            _board(par, state, rec, e, arg, t)
        else:  # DWELL: depart, free the stop, travel on
            k = bus_int[e, arg, STOP]
            state.stop_real[e, k] = t
            state.stop_busy[e, k] = 0
            _schedule(ev_time, ev_int, ep_int, e, t, RELEASE, k)
            _schedule(ev_time, ev_int, ep_int, e, t + par.rt, TRAVEL, arg)


@_kernel
def _advance(actions, par, state, rec, pending):
    """Deliver the actions of the pending decisions, run every episode until it is blocked, and
    gather the new pending decisions into the first rows of ``pending``.

    ``actions`` answer the previous round's rows in order (episode, then arrival order). Returns the
    number of new rows, or -1 if an action is out of range (nothing is changed then).
    """
    for i in range(actions.shape[0]):
        if actions[i] < 0 or actions[i] >= par.n_actions:
            return -1
    ep_int, bus_int = state.ep_int, state.bus_int
    row = 0
    rows = 0
    for e in range(ep_int.shape[0]):
        if ep_int[e, DONE]:
            continue
        for p in range(ep_int[e, N_PENDING]):
            b = ep_int[e, PENDING + p]
            bus_int[e, b, ACTION] = actions[row]
            row += 1
            _schedule(state.ev_time, state.ev_int, ep_int, e, state.ep_real[e, NOW], DECISION, b)
        ep_int[e, N_PENDING] = 0
        _run_episode(par, state, rec, e)
        for p in range(ep_int[e, N_PENDING]):
            b = ep_int[e, PENDING + p]
            for i in range(OBS_DIM):  # element by element: a slice copy needs the runtime
                pending.obs[rows, i] = state.bus_real[e, b, OBS + i]
            pending.ids[EPISODE, rows] = e
            pending.ids[AGENT, rows] = b
            pending.ids[INDEX, rows] = bus_int[e, b, N_DEC] - 1
            rows += 1
    return rows


class BusBatch:
    """A batch of episodes advanced round by round (see the module docstring)."""

    def __init__(self, cfg: BusConfig, n_episodes: int):
        require(n_episodes >= 1, "n_episodes", "an integer >= 1", n_episodes)
        self.cfg = cfg
        e, n, k = n_episodes, cfg.n_buses, cfg.n_stops
        m = cfg.max_arrivals_per_bus
        cap = 2 * n  # scheduled at once: one event of each bus, plus the RELEASE of the stop it left
        self._par = _Params(int(cfg.n_actions), np.asarray(cfg.alight_fraction, float),
                            np.asarray(cfg.arrival_rate, float), int(cfg.l_max),
                            float(cfg.travel_time), float(cfg.t_alight), float(cfg.t_board),
                            float(cfg.headway), float(cfg.t_hold), float(cfg.gamma),
                            float(cfg.horizon))
        self._state = _State(
            ep_real=np.zeros((e, 2)), ep_int=np.zeros((e, PENDING + n), np.int64),
            ev_time=np.full((e, cap), np.inf), ev_int=np.zeros((e, cap, 3), np.int64),
            bus_real=np.zeros((e, n, OBS + OBS_DIM)), bus_int=np.zeros((e, n, 6), np.int64),
            stop_real=np.zeros((e, k)), stop_busy=np.zeros((e, k), np.int64))
        self._rec = _Record(dec=np.zeros((e, n, m, OBS_DIM + 3)), arr=np.zeros((e, n * m, 7)))
        self._pending = _Pending(obs=np.zeros((e * n, OBS_DIM)), ids=np.zeros((3, e * n), np.int64))
        st = self._state
        st.bus_int[:, :, TICKET] = -1
        # SimPy starts one process per bus with an URGENT initialisation event, in bus order.
        st.ev_time[:, :n] = 0.0
        st.ev_int[:, :n, ID] = np.arange(n)
        st.ev_int[:, :n, KIND] = INIT
        st.ev_int[:, :n, ARG] = np.arange(n)
        st.ep_int[:, NEXT_ID] = n
        self._decisions = self._gathered(0)

    @property
    def done(self) -> np.ndarray:
        """(E,) bool: the episode has reached the horizon."""
        return self._state.ep_int[:, DONE] == 1

    @property
    def ep_return(self) -> np.ndarray:
        """(E,) the undiscounted return so far (sum of every arrival's reward)."""
        return self._state.ep_real[:, RETURN]

    def advance(self, actions: np.ndarray) -> DecisionBatch:
        """Answer the pending decisions (one action per row of the last batch), run until blocked,
        and return the new pending decisions (empty once every episode has ended)."""
        actions = np.asarray(actions)
        require(len(actions) == len(self._decisions), "actions", "one action per pending decision",
                len(actions))
        require(len(actions) == 0 or np.issubdtype(actions.dtype, np.integer), "actions",
                "integers", actions.dtype)
        rows = _advance(np.ascontiguousarray(actions, np.int64), self._par, self._state, self._rec,
                        self._pending)
        if rows < 0:
            raise UsageError("action", f"an integer in 0..{self.cfg.n_actions - 1} "
                             "(a hold of a * T_hold)", actions.tolist())
        self._decisions = self._gathered(rows)
        return self._decisions

    def _gathered(self, rows: int) -> DecisionBatch:
        """The first ``rows`` rows of the decision buffers, copied (the policy may keep them)."""
        obs, ids = self._pending
        return DecisionBatch(obs=obs[:rows].copy(), episode=ids[EPISODE, :rows].copy(),
                             agent=ids[AGENT, :rows].copy(), index=ids[INDEX, :rows].copy())

    def decisions(self) -> DecisionBatch:
        """The pending decisions (those the last :meth:`advance` returned)."""
        return self._decisions

    def arrivals(self) -> dict[str, np.ndarray]:
        """Every arrival of every episode, in processing order: episode, time (s), bus, stop
        (0-based), h (min), load at arrival, alighting U and boarding B."""
        counts = self._state.ep_int[:, N_ARR]
        arr = _compacted(self._rec.arr, counts)
        ints = arr.astype(np.int64)  # only the integer columns are read from it
        return dict(episode=np.repeat(np.arange(len(counts)), counts), time=arr[:, TIME],
                    bus=ints[:, A_BUS],
                    stop=ints[:, A_STOP], h=arr[:, HEADWAY], load=ints[:, A_LOAD],
                    alight=ints[:, A_ALIGHT], board=ints[:, A_BOARD])

    def to_rollout(self) -> Rollout:
        require(bool(self.done.all()), "rollout", "taken after every episode has ended")
        n_dec = self._state.bus_int[:, :, N_DEC]
        e, n = n_dec.shape
        lengths = n_dec.reshape(-1)
        dec = _compacted(self._rec.dec.reshape(e * n, *self._rec.dec.shape[2:]), lengths)
        return Rollout(
            obs=np.ascontiguousarray(dec[:, :OBS_DIM]), actions=dec[:, D_ACTION].astype(np.int64),
            rewards=dec[:, D_REWARD].copy(), durations=dec[:, D_DURATION].copy(),
            path_start=np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
            path_episode=np.repeat(np.arange(e), n), path_agent=np.tile(np.arange(n), e),
            episode_return=self.ep_return.copy(), info={"arrivals": self.arrivals()})


@_kernel
def _compact(rows, counts, out):
    o = 0
    for g in range(rows.shape[0]):
        for i in range(counts[g]):
            for w in range(rows.shape[2]):
                out[o, w] = rows[g, i, w]
            o += 1


def _compacted(rows: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """The first ``counts[g]`` rows of each group ``rows[g]``, one after another (a compiled loop:
    numpy's boolean-mask indexing took a quarter of a rollout)."""
    out = np.empty((int(counts.sum()), rows.shape[2]))
    _compact(rows, counts, out)
    return out


def drive(batch: Any, policy: Policy) -> None:
    """Run a batch (fast or reference) to the end: one policy call per round."""
    decisions = batch.advance(np.zeros(0, np.int64))
    while len(decisions):
        decisions = batch.advance(np.asarray(policy(decisions)))


class BusEnv:
    """The fast engine as a :class:`repro.core.rollout.BatchEnv`."""

    name = "bus"
    obs_dim = OBS_DIM

    def __init__(self, cfg: BusConfig | None = None):
        self.cfg = cfg or BusConfig()
        self.n_actions = self.cfg.n_actions
        self.n_agents = self.cfg.n_buses
        self.gamma = self.cfg.gamma

    def start(self, n_episodes: int) -> BusBatch:
        return BusBatch(self.cfg, n_episodes)

    def rollout(self, policy: Policy, n_episodes: int,
                seed: int | np.random.SeedSequence = 0) -> Rollout:
        """The environment is deterministic, so ``seed`` is unused (only the policy is random)."""
        batch = self.start(n_episodes)
        drive(batch, policy)
        return batch.to_rollout()
