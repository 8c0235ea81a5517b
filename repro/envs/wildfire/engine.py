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

``_advance`` records the policy's last actions, then runs every live episode until it is blocked
(its next event is the end of a decision latency whose action the policy has not given yet) or
over. Python then hands all pending observations of the batch to the policy in ONE call and
repeats. Decisions are appended to a flat log and placed into contiguous paths at the end.
A policy that offers a compiled form (:class:`repro.core.policy_kernel.CompiledPolicy`, as the
learner's sampler does) is applied to rounds of a few decisions inside the kernel
(``_act_and_advance``), with the same actions as its call: learned policies make episodes of
hundreds of thousands of decisions, whose rounds near the end hold one row or a few, and one such
600-episode rollout, profiled, spent 95% of its time in the round trips to Python.

Speed. A rollout of the training batch (600 episodes, about 14,000 decisions and 32,000 events)
takes about 50 rounds, so the per-event cost dominates. An episode's state is one numpy record (a
row of a structured array, ``state_dtype``), and so are the parameters (``params_record``) and each
decision's log row (``log_dtype``): numba hands a record to a function as a bare pointer, whereas
an array, or every array of a tuple, costs a reference-count update per call. A round visits only
the live episodes (a list it compacts), each once, and its first read of an episode misses the
cache, so what tells whether the episode is blocked comes first in the record, and the record is
small: the hold durations stay in the draws' array, a heap entry is 16 bytes (its time and one
integer packing priority, sequence number, kind and subject, whose order is the order of
(priority, sequence)), and the reward of a UAV's running decision accrues in the record. A log
row is written when its decision is observed (observation, time, ids), gets its action at the
next round, and is closed (reward, duration) by the UAV's next observation or the episode's end;
the kernel never reads it back. An observation sorts the fires by distance once and counts the
interest parties once. The policy reads views of the log's new rows; its answers are
range-checked in the kernel (numpy's checks cost more than a small round's simulation). At the
end a compiled loop places the rows into paths: a row's place is its path's start plus its
decision number (no sort). The state and the log are allocated uninitialised: the kernels write
every field before reading it. The hold durations are drawn for the whole batch up front (the
committed random streams), which costs about a third of a rollout without the policy.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from repro.core.policy_kernel import MAX_ROWS, act_row
from repro.core.rollout import BadActions, DecisionBatch, Policy, Rollout, check_actions
from repro.envs.wildfire.params import (DIST, FIRES, HEALTH, INTEREST, LEVEL, OBS_PER_FIRE, OWN_X,
                                        OWN_Y, STATUS, EpisodeDraws, WildfireConfig,
                                        draw_episodes, fire_positions, fs_delay, rank_key)

URGENT, NORMAL = 0, 1
"""SimPy's priorities: an interrupt or a process start at time t comes before any timeout at t."""
(LATENCY, ACTION, EXTINGUISH, INT_UAV, INT_FIRE, CLOCK, ACT_START, INT_ACT, ACT_END, ANY_OF,
 BURN_FAIL, BURN_START, BURN_END, END_HOP) = range(14)
"""Event kinds: decision latency over, macro-action over, fire out, UAV process interrupted (its
fire went out: in scheduling order, or in the latency without Q4), fire interrupted (its party
changed), T_max reached. The released order's hops, SimPy's intermediate events there: the action
sub-process starts (URGENT), is interrupted (URGENT), ends or fails, then the AnyOf the UAV waits
on triggers; the burn sub-process fails (interrupted), restarts (URGENT), ends (its fire is out);
the episode's end condition (END_HOP: ``who`` more hops to go)."""
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

WHO_BITS, KIND_BITS, PRIO_SHIFT = 20, 4, 62
"""A heap entry's integer key: priority << 62 | sequence << 24 | kind << 20 | who. Sequence numbers
are unique within an episode, so comparing keys compares (priority, sequence) as SimPy does; the
38 bits of the sequence outlast any episode, and who (an agent or fire index) must stay below
2^20 (params check the number of UAVs)."""
SEQ_SHIFT = WHO_BITS + KIND_BITS

# Flags inside records are int8 (numba does not support nested boolean arrays); int32 counters and
# indices keep the state record small.
jit = njit(cache=True)

fs_delay_nb = jit(fs_delay)
rank_key_nb = jit(rank_key)


def params_record(cfg: WildfireConfig) -> np.ndarray:
    """The (1,) structured array of the kernels' parameters."""
    fires = fire_positions(cfg)
    rec = np.zeros(1, np.dtype([
        ("n_agents", np.int64), ("n_fires", np.int64), ("n_obs", np.int64), ("v", np.float64),
        ("dt", np.float64), ("latency", np.float64), ("tol", np.float64), ("gamma", np.float64),
        ("r_ext", np.float64), ("r_pen", np.float64), ("t_health", np.float64),
        ("t_max", np.float64), ("max_dec", np.int64), ("rank_res", np.float64),
        ("q1", np.bool_), ("q2", np.bool_), ("q3", np.bool_), ("q4", np.bool_), ("q5", np.bool_),
        ("q6", np.bool_), ("released", np.bool_), ("round_neg", np.bool_),
        ("cut_goes_on", np.bool_),
        ("fires", np.float64, fires.shape)], align=True))
    rec[0] = (cfg.n_agents, len(fires), cfg.n_observed, cfg.v_uav, cfg.dt or 0.0,
              cfg.decision_latency, cfg.at_fire_tol, cfg.gamma, cfg.r_ext, cfg.r_pen,
              cfg.t_health, cfg.t_max, cfg.max_decisions or 0, cfg.ranking_resolution,
              cfg.quirk_q1_stale_attack, cfg.quirk_q2_penalty_party_only,
              cfg.quirk_q3_unclamped_health, cfg.quirk_q4_latency_not_interrupted,
              cfg.quirk_q5_discount_from_action_start, cfg.quirk_q6_short_flight_stays,
              cfg.same_instant_order == "released",
              cfg.fs_round_negative_delays, cfg.cut_flight_continues, fires)
    return rec


def state_dtype(cfg: WildfireConfig) -> np.dtype:
    """One episode's state: scalars, then (N, ...) UAV fields, (K,) fire fields, the event heap."""
    n, k, f8, i8, i4, i1 = (cfg.n_agents, len(fire_positions(cfg)), np.float64, np.int64,
                            np.int32, np.int8)
    return np.dtype([
        # what a round reads of every episode first, to tell whether it is blocked, is adjacent:
        # each episode's first visit of a round misses the cache
        ("done", np.bool_), ("truncated", np.bool_), ("n_alive", i4), ("now", f8), ("t_end", f8),
        ("events", i8),
        ("uwait", i8, n), ("act", i8, n),
        # the event heap: packed key (see WHO_BITS) and time; its size; the next sequence; the
        # now-queues of URGENT and NORMAL events due now (see _push): keys, first, size
        ("hkey", i8, heap_capacity(cfg)), ("ht", f8, heap_capacity(cfg)), ("hn", i4),
        ("seq", i8), ("qu", i8, queue_capacity(cfg)), ("qu_0", i4), ("qu_n", i4),
        ("qn", i8, queue_capacity(cfg)), ("qn_0", i4), ("qn_n", i4),
        # UAV motion
        ("pos", f8, (n, 2)), ("origin", f8, (n, 2)), ("goal", f8, (n, 2)), ("t_dep", f8, n),
        ("length", f8, n), ("flying", i1, n),
        # UAV bookkeeping; the running decision (its action is ``act``, -1 until the policy gave
        # it): its log row, time and discounted reward so far
        ("interest", i4, n), ("attacking", i4, n), ("in_party", i1, n), ("n_holds", i4, n),
        ("rank", i4, (n, cfg.n_observed)), ("n_dec", i4, n), ("returns", f8, n),
        ("cur", i8, n), ("t_obs", f8, n), ("rew", f8, n), ("t_disc", f8, n),
        # when the UAV joined its interest party (a counter: the party's order); whether it waits
        # its latency; whether its action sub-process is alive (released order), and whether the
        # action ended by an interrupt
        ("joined", i8, n), ("joins", i8), ("in_lat", i1, n), ("acting", i1, n), ("cut", i1, n),
        # fires; whether the burn sub-process is alive (released order)
        ("alive", i1, k), ("health", f8, k), ("t_update", f8, k), ("party", i4, k),
        ("fwait", i8, k), ("burning", i1, k),
        # scratch of an observation: the observing UAV's distance to every fire and its ranking
        # key, the fires in ranking order, the size of every fire's interest party
        ("fire_dist", f8, k), ("fire_key", f8, k), ("fire_order", i4, k), ("fire_party", i4, k),
    ], align=True)


def log_dtype(obs_dim: int) -> np.dtype:
    """One decision: its observation and action, reward and duration once it closed, its time,
    episode, agent and decision number (int64: the policy gets these as they are)."""
    f8, i8 = np.float64, np.int64
    return np.dtype([("obs", f8, obs_dim), ("time", f8), ("rew", f8), ("dur", f8), ("act", i8),
                     ("ep", i8), ("agent", i8), ("idx", i8)], align=True)


# --- event heap ----------------------------------------------------------------------------------

@jit
def _push(s, delay, prio, kind, who):
    """Schedule an event ``delay`` after now (SimPy: time now + delay); return its sequence.

    An event due now goes to the now-queue of its priority, in order, not the heap: every event
    the heap holds for now was scheduled earlier (sequence numbers grow), so SimPy's order at
    now is the URGENT queue, then the heap's events due now (all NORMAL timeouts), then the NORMAL
    queue. The released order's hops and the interrupts all take the queues."""
    seq = s.seq
    s.seq = seq + 1
    t = s.now + delay
    key = (np.int64(prio) << PRIO_SHIFT) | (seq << SEQ_SHIFT) | (np.int64(kind) << WHO_BITS) | who
    if t != s.now:
        _heap_insert(s, t, key)
    elif prio == URGENT:
        s.qu[(s.qu_0 + s.qu_n) % s.qu.shape[0]] = key
        s.qu_n += 1
    else:
        s.qn[(s.qn_0 + s.qn_n) % s.qn.shape[0]] = key
        s.qn_n += 1
    return seq


@jit
def _heap_insert(s, t, key):
    n = s.hn
    s.hn = n + 1
    while n > 0:  # sift the new entry up, moving parents into the hole
        parent = (n - 1) // 2
        pt = s.ht[parent]
        if pt < t or (pt == t and s.hkey[parent] < key):
            break
        s.ht[n] = pt
        s.hkey[n] = s.hkey[parent]
        n = parent
    s.ht[n] = t
    s.hkey[n] = key


@jit
def _next_anyway(s, prio):
    """Whether an event pushed now with priority ``prio`` would be the next one: then a hop can
    run at once instead (the released order's chains of hops mostly do, in ED)."""
    if s.qu_n > 0:
        return False
    return prio == URGENT or (s.qn_n == 0 and (s.hn == 0 or s.ht[0] > s.now))


@jit
def _next_source(s):
    """Where the next event is: 0 the URGENT now-queue, 1 the heap, 2 the NORMAL now-queue."""
    if s.qu_n > 0:
        return 0
    if s.qn_n > 0 and (s.hn == 0 or s.ht[0] != s.now):
        return 2
    return 1


@jit
def _next_key(s):
    """The key of the next event."""
    src = _next_source(s)
    return s.qu[s.qu_0] if src == 0 else s.qn[s.qn_0] if src == 2 else s.hkey[0]


@jit
def _pop(s):
    """Remove the next event; return its time and key."""
    src = _next_source(s)
    if src == 0:
        key = s.qu[s.qu_0]
        s.qu_0 = (s.qu_0 + 1) % s.qu.shape[0]
        s.qu_n -= 1
        return s.now, key
    if src == 2:
        key = s.qn[s.qn_0]
        s.qn_0 = (s.qn_0 + 1) % s.qn.shape[0]
        s.qn_n -= 1
        return s.now, key
    t0, k0 = s.ht[0], s.hkey[0]
    n = s.hn - 1
    s.hn = n
    t, key = s.ht[n], s.hkey[n]  # the last entry sifts down from the root
    i = 0
    while True:
        c = 2 * i + 1
        if c >= n:
            break
        if c + 1 < n and (s.ht[c + 1] < s.ht[c] or
                          (s.ht[c + 1] == s.ht[c] and s.hkey[c + 1] < s.hkey[c])):
            c += 1
        if t < s.ht[c] or (t == s.ht[c] and key < s.hkey[c]):
            break
        s.ht[i] = s.ht[c]
        s.hkey[i] = s.hkey[c]
        i = c
    s.ht[i] = t
    s.hkey[i] = key
    return t0, k0


@jit
def _unpack(key):
    """(sequence, kind, who) of a heap key."""
    who = key & ((1 << WHO_BITS) - 1)
    kind = (key >> WHO_BITS) & ((1 << KIND_BITS) - 1)
    seq = (key >> SEQ_SHIFT) & ((np.int64(1) << (PRIO_SHIFT - SEQ_SHIFT)) - 1)
    return seq, kind, who


# --- model (mirrors reference.WildfireModel method by method) ------------------------------------

@jit
def _dist(ax, ay, bx, by):
    return math.sqrt((bx - ax) * (bx - ax) + (by - ay) * (by - ay))


@jit
def _health_now(s, p, j):
    left = s.health[j] - s.party[j] * (s.now - s.t_update[j])
    if p.q3:
        return left
    return max(0.0, left) if s.alive[j] else 0.0


@jit
def _close(s, r, i):
    """UAV i's running decision (log row r) ends now."""
    r.rew = s.rew[i]
    r.dur = s.now - s.t_obs[i]


@jit
def _position(s, p, i):
    """Where UAV i is now: on its flight's segment, or where it landed."""
    if not s.flying[i]:
        return s.pos[i, 0], s.pos[i, 1]
    length = s.length[i]
    if p.q6 and length < p.tol:
        return s.origin[i, 0], s.origin[i, 1]
    if length == 0:
        return s.goal[i, 0], s.goal[i, 1]
    frac = min(1.0, p.v * (s.now - s.t_dep[i]) / length)
    return (s.origin[i, 0] + frac * (s.goal[i, 0] - s.origin[i, 0]),
            s.origin[i, 1] + frac * (s.goal[i, 1] - s.origin[i, 1]))


@jit
def _observe(s, p, r, row, e, i):
    """UAV i observes into log row r (number ``row``) and waits the decision latency."""
    now = s.now
    sojourn = now - s.t_obs[i] if s.n_dec[i] > 0 else 0.0
    x, y = _position(s, p, i)
    o = r.obs
    o[OWN_X], o[OWN_Y] = x, y
    dist, key, order, party = s.fire_dist, s.fire_key, s.fire_order, s.fire_party
    for j in range(p.n_fires):  # insertion sort by (ranking key, index): lower index wins ties
        d = _dist(x, y, p.fires[j, 0], p.fires[j, 1])
        dist[j] = d
        kj = rank_key_nb(d, p.rank_res)
        key[j] = kj
        at = j
        while at > 0 and key[order[at - 1]] > kj:
            order[at] = order[at - 1]
            at -= 1
        order[at] = j
        party[j] = 0
    for a in range(p.n_agents):
        if s.interest[a] >= 0:
            party[s.interest[a]] += 1
    for k in range(p.n_obs):
        best = order[k]
        s.rank[i, k] = best
        base = FIRES + OBS_PER_FIRE * k
        o[base + DIST] = dist[best]
        o[base + LEVEL] = 1.0
        o[base + INTEREST] = party[best]
        o[base + STATUS] = 1.0 if s.alive[best] else 0.0
        o[base + HEALTH] = _health_now(s, p, best)
    o[FIRES + OBS_PER_FIRE * p.n_obs] = sojourn
    r.time = now
    r.ep = e
    r.agent = i
    r.idx = s.n_dec[i]
    s.n_dec[i] += 1
    s.cur[i] = row
    s.act[i] = -1
    s.t_obs[i] = now
    if not p.q5:
        s.t_disc[i] = now
    s.rew[i] = 0.0
    s.in_lat[i] = True
    s.uwait[i] = _push(s, p.latency, NORMAL, LATENCY, i)


@jit
def _accrue(s, p, i, r):
    s.rew[i] += math.exp(-p.gamma * (s.now - s.t_disc[i])) * r
    s.returns[i] += r


@jit
def _party_change(s, p, j, delta):
    if not s.alive[j]:
        return
    now = s.now
    s.health[j] = s.health[j] - s.party[j] * (now - s.t_update[j])
    s.t_update[j] = now
    s.party[j] += delta
    if not p.released:
        _push(s, 0.0, URGENT, INT_FIRE, j)
    elif s.burning[j]:  # else it ended at this instant: the fire goes out all the same
        _push(s, 0.0, URGENT, INT_FIRE, j)


@jit
def _penalise(s, p, j):
    if s.party[j] < 2:
        return
    for i in range(p.n_agents):
        member = s.in_party[i] and s.attacking[i] == j
        if member or not p.q2:
            _accrue(s, p, i, p.r_pen)


@jit
def _join_interest(s, i, j):
    s.interest[i] = j
    s.joined[i] = s.joins
    s.joins += 1


@jit
def _start_action(s, p, i, a, hold):
    """UAV i starts action a; ``hold`` is its next hold duration (used if a holds)."""
    now = s.now
    if p.q5:
        s.t_disc[i] = now
    _land(s, p, i, True)  # a cut flight that went on until now
    s.interest[i] = -1
    if a < p.n_obs:
        target = s.rank[i, a]
        _join_interest(s, i, target)
        if s.in_party[i]:
            s.in_party[i] = False
            _party_change(s, p, s.attacking[i], -1)
        if not p.q1:
            s.attacking[i] = -1
        ox, oy = s.pos[i, 0], s.pos[i, 1]
        gx, gy = p.fires[target, 0], p.fires[target, 1]
        length = _dist(ox, oy, gx, gy)
        s.origin[i, 0], s.origin[i, 1] = ox, oy
        s.goal[i, 0], s.goal[i, 1] = gx, gy
        s.t_dep[i] = now
        s.length[i] = length
        s.flying[i] = True
        d = fs_delay_nb(now, length / p.v, p.dt, p.round_neg)
    else:
        x, y = s.pos[i, 0], s.pos[i, 1]
        for j in range(p.n_fires):
            if _dist(x, y, p.fires[j, 0], p.fires[j, 1]) < p.tol:
                _join_interest(s, i, j)
                if s.attacking[i] != j:
                    s.attacking[i] = j
                    if s.alive[j]:
                        s.in_party[i] = True
                        _party_change(s, p, j, 1)
                        _penalise(s, p, j)
                break
        s.n_holds[i] += 1
        d = fs_delay_nb(now, hold, p.dt, p.round_neg)
    s.uwait[i] = _push(s, d, NORMAL, ACTION, i)


@jit
def _land(s, p, i, cut):
    """The flight ends now: at its goal if it finished, else where it got to."""
    if not s.flying[i]:
        return
    if cut or (p.q6 and s.length[i] < p.tol):
        s.pos[i, 0], s.pos[i, 1] = _position(s, p, i)
    else:
        s.pos[i, 0], s.pos[i, 1] = s.goal[i, 0], s.goal[i, 1]
    s.flying[i] = False


@jit
def _replan(s, p, j):
    if s.party[j] == 0:
        s.fwait[j] = -1  # idle until the party changes
    else:
        d = fs_delay_nb(s.now, s.health[j] / s.party[j], p.dt, p.round_neg)
        s.fwait[j] = _push(s, d, NORMAL, EXTINGUISH, j)


@jit
def _interrupt(s, p, i):
    """A fire UAV i is interested in went out."""
    if s.in_lat[i]:
        if not p.q4:
            _push(s, 0.0, URGENT, INT_UAV, i)  # drop the pending decision
    elif not p.released:
        _push(s, 0.0, URGENT, INT_UAV, i)
    elif s.acting[i]:  # else it ended at this instant: the UAV will observe
        _push(s, 0.0, URGENT, INT_ACT, i)


@jit
def _extinguish(s, p, j):
    s.alive[j] = False
    s.n_alive -= 1
    for i in range(p.n_agents):
        _accrue(s, p, i, p.r_ext)
    if p.released:  # in the order they joined the interest party
        last = np.int64(-1)
        while True:
            nxt, first = -1, np.int64(0)
            for i in range(p.n_agents):
                if s.interest[i] == j and s.joined[i] > last and (nxt < 0 or s.joined[i] < first):
                    nxt, first = i, s.joined[i]
            if nxt < 0:
                break
            _interrupt(s, p, nxt)
            last = first
    else:
        for i in range(p.n_agents):
            if s.interest[i] == j:
                _interrupt(s, p, i)


@jit
def _fire_out(s, log, p, j):
    """Released order: fire j's burn sub-process ended, the fire goes out; after the last one the
    conditions "fire out", "all out", "all out or T_max" trigger in turn."""
    _extinguish(s, p, j)
    if s.n_alive == 0:
        _push(s, 0.0, NORMAL, END_HOP, 2)


@jit
def _end(s, log, p):
    """The episode ends now: every UAV's running decision closes."""
    s.done = True
    s.t_end = s.now
    for i in range(p.n_agents):
        _close(s, log[s.cur[i]], i)


@jit
def _act(s, p, holds, e, i):
    """UAV i starts the action the policy gave it."""
    a = s.act[i]
    hold = holds[e, i, s.n_holds[i] % holds.shape[2]] if a == p.n_obs else 0.0
    _start_action(s, p, i, a, hold)


@jit
def _to_uav(s, log, p, e, row, i, hops):
    """The end of UAV i's macro-action reaches it ``hops`` NORMAL events later (2: the action
    sub-process ending, then the AnyOf; 1: the AnyOf). Returns the next free row."""
    if _next_anyway(s, NORMAL):
        s.events += hops
        return _macro_action_over(s, log, p, e, row, i, s.cut[i])
    _push(s, 0.0, NORMAL, ACT_END if hops == 2 else ANY_OF, i)
    return row


@jit
def _burn_restarts(s, p, j, hops):
    """Fire j's failed burn sub-process restarts ``hops`` events later (2: its failure, NORMAL,
    then its start, URGENT; 1: the start)."""
    if _next_anyway(s, NORMAL if hops == 2 else URGENT):
        s.events += hops
        s.burning[j] = True
        _replan(s, p, j)
    else:
        _push(s, 0.0, NORMAL if hops == 2 else URGENT, BURN_FAIL if hops == 2 else BURN_START, j)


@jit
def _macro_action_over(s, log, p, e, row, i, cut):
    """UAV i's macro-action ended (cut: by an interrupt): it observes again (log row ``row``),
    unless that was its last allowed decision; returns the next free row."""
    if not (cut and p.cut_goes_on):
        _land(s, p, i, cut)
    _close(s, log[s.cur[i]], i)
    if s.n_dec[i] == p.max_dec:  # 0 (no limit) never: n_dec >= 1 here
        s.truncated = True
        _end(s, log, p)
        return row
    _observe(s, p, log[row], row, e, i)
    return row + 1


# --- kernels -------------------------------------------------------------------------------------

@jit
def _setup(states, log, used, params, starts, slots):
    """Every field of the (uninitialised) states of episodes ``slots`` (their UAVs start at
    ``starts``, in that order), then time 0: every UAV observes (in index order), and the T_max
    clock starts (in the released order before, as the released code creates it before running
    its processes)."""
    p = params[0]
    row = used[0]
    for j in range(len(slots)):
        e = slots[j]
        s = states[e]
        s.now = 0.0
        s.t_end = np.nan
        s.events = 0
        s.done = False
        s.truncated = False
        s.n_alive = p.n_fires
        s.hn = 0
        s.seq = 0
        s.qu_0 = s.qu_n = s.qn_0 = s.qn_n = 0
        s.joins = 0
        for i in range(p.n_agents):
            s.pos[i, 0], s.pos[i, 1] = starts[j, i, 0], starts[j, i, 1]
            s.flying[i] = False  # origin, goal, t_dep and length are set on take-off
            s.interest[i] = -1
            s.attacking[i] = -1
            s.in_party[i] = False
            s.n_holds[i] = 0
            s.n_dec[i] = 0
            s.uwait[i] = -1
            s.joined[i] = 0
            s.acting[i] = False
            s.cut[i] = False
            s.t_disc[i] = 0.0
            s.returns[i] = 0.0  # rank, cur, t_obs, rew, in_lat: set by the first observation
        for j in range(p.n_fires):
            s.alive[j] = True
            s.health[j] = p.t_health
            s.t_update[j] = 0.0
            s.party[j] = 0
            s.fwait[j] = -1
            s.burning[j] = True  # the burn sub-process waits for a party
        if p.released:
            _push(s, p.t_max, NORMAL, CLOCK, 0)
        for i in range(p.n_agents):
            _observe(s, p, log[row], row, e, i)
            row += 1
        if not p.released:
            _push(s, p.t_max, NORMAL, CLOCK, 0)
    used[0] = row


@jit
def _advance(states, live, log, used, params, holds, actions, first):
    """Record the actions of log rows first, first + 1, ...; then run every live episode until it is
    blocked (its next event is the end of a decision latency whose action is still -1) or over, or
    until the log or a heap is full. Returns the status and the first row now without an action.
    BAD_ACTION, and nothing changed, if an action is out of range (checked here: numpy's checks cost
    more than a small round's simulation). ``live[0]`` episodes are live, ``live[1:]`` (in order);
    those that end leave the list, so later rounds do not visit them."""
    p = params[0]
    for k in range(len(actions)):
        if actions[k] < 0 or actions[k] > p.n_obs:  # the actions are 0..n_obs
            return BAD_ACTION, first
    for k in range(len(actions)):
        r = log[first + k]
        r.act = actions[k]
        s = states[r.ep]
        if s.cur[r.agent] == first + k:  # else superseded: its latency's end is stale
            s.act[r.agent] = actions[k]
    row = used[0]
    status = OK
    n_live = 0
    for q in range(live[0]):
        e = live[1 + q]
        s = states[e]
        while not s.done:
            sq, kind, who = _unpack(_next_key(s))
            if kind == LATENCY and sq == s.uwait[who] and s.act[who] < 0:
                break  # the policy has not decided yet
            if row >= len(log):
                status = GROW_LOG
                break
            room = p.n_agents + 3  # what one event may push, at most
            if (s.hn + room > s.hkey.shape[0] or s.qu_n + room > s.qu.shape[0]
                    or s.qn_n + room > s.qn.shape[0]):
                status = HEAP_FULL
                break
            t, key = _pop(s)
            sq, kind, who = _unpack(key)
            s.now = t
            s.events += 1
            if kind == LATENCY:
                if sq == s.uwait[who]:
                    s.in_lat[who] = False
                    if not p.released:
                        _act(s, p, holds, e, who)
                    else:  # the action sub-process starts
                        s.acting[who] = True
                        if _next_anyway(s, URGENT):
                            s.events += 1
                            _act(s, p, holds, e, who)
                        else:
                            _push(s, 0.0, URGENT, ACT_START, who)
            elif kind == ACT_START:
                _act(s, p, holds, e, who)
            elif kind == ACTION:
                if sq == s.uwait[who]:
                    if p.released:  # the sub-process ends
                        s.acting[who] = False
                        s.cut[who] = False
                        row = _to_uav(s, log, p, e, row, who, 2)
                    else:
                        row = _macro_action_over(s, log, p, e, row, who, False)
            elif kind == INT_UAV:
                row = _macro_action_over(s, log, p, e, row, who, True)
            elif kind == INT_ACT:
                if s.acting[who]:  # the sub-process fails
                    s.acting[who] = False
                    s.cut[who] = True
                    s.uwait[who] = -1
                    row = _to_uav(s, log, p, e, row, who, 2)
            elif kind == ACT_END:
                row = _to_uav(s, log, p, e, row, who, 1)
            elif kind == ANY_OF:
                row = _macro_action_over(s, log, p, e, row, who, s.cut[who])
            elif kind == EXTINGUISH:
                if sq == s.fwait[who]:
                    if not p.released:
                        _extinguish(s, p, who)
                        if s.n_alive == 0:
                            _end(s, log, p)
                    else:  # the burn sub-process ends
                        s.burning[who] = False
                        if _next_anyway(s, NORMAL):
                            s.events += 1
                            _fire_out(s, log, p, who)
                        else:
                            _push(s, 0.0, NORMAL, BURN_END, who)
            elif kind == BURN_END:
                _fire_out(s, log, p, who)
            elif kind == INT_FIRE:
                if p.released:
                    if s.burning[who]:  # the burn sub-process fails
                        s.burning[who] = False
                        s.fwait[who] = -1
                        _burn_restarts(s, p, who, 2)
                elif s.alive[who]:
                    _replan(s, p, who)
            elif kind == BURN_FAIL:  # the fire restarts its burn sub-process
                _burn_restarts(s, p, who, 1)
            elif kind == BURN_START:
                s.burning[who] = True
                _replan(s, p, who)
            elif kind == END_HOP:
                if who > 0:
                    _push(s, 0.0, NORMAL, END_HOP, who - 1)
                else:
                    _end(s, log, p)
            elif p.released:  # CLOCK: then the condition "all out or T_max"
                _push(s, 0.0, NORMAL, END_HOP, 0)
            else:
                _end(s, log, p)
        if not s.done:
            live[1 + n_live] = e
            n_live += 1
        if status != OK:  # keep the episodes not visited
            for r in range(q + 1, live[0]):
                live[1 + n_live] = live[1 + r]
                n_live += 1
            break
    live[0] = n_live
    used[0] = row
    return status, first + len(actions)


@jit
def _act_and_advance(states, live, log, used, params, holds, first, weights, biases, mean, scale,
                     rng):
    """Act on the pending round of at most MAX_ROWS decisions as the policy's call would (its
    last five arguments: a CompiledPolicy) and :func:`_advance`; repeat while the next round is as
    small. Long episodes end in many rounds of a row or a few, each a return to Python otherwise.
    Returns as :func:`_advance` does. The actions made here are in range: the network has one
    output per action."""
    own = np.empty(MAX_ROWS, np.int64)
    while True:
        n = used[0] - first
        for k in range(n):
            own[k] = act_row(log[first + k].obs, weights, biases, mean, scale, rng.random())
        status, first = _advance(states, live, log, used, params, holds, own[:n], first)
        if status != OK or not 0 < used[0] - first <= MAX_ROWS:
            return status, first


@jit
def _paths(rows, path_start, n_agents, obs, actions, rewards, durations, times):
    """The log's rows into path order. A row's place is its path's start plus its decision number
    (rows of a path come in decision order, so this is the stable sort by path); the copy then
    gathers the rows in that order (reading scattered rows beats writing scattered ones)."""
    order = np.empty(len(rows), np.int64)
    for r in range(len(rows)):
        rec = rows[r]
        order[path_start[rec.ep * n_agents + rec.agent] + rec.idx] = r
    for d in range(len(rows)):
        rec = rows[order[d]]
        o = rec.obs
        for w in range(obs.shape[1]):
            obs[d, w] = o[w]
        actions[d] = rec.act
        rewards[d] = rec.rew
        durations[d] = rec.dur
        times[d] = rec.time


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

    def act_compiled(self, compiled: tuple) -> None:
        """Act as a compiled policy's call would, inside the kernel, on this small round and the
        next ones as small (see ``_act_and_advance``)."""
        env = self.env
        status, self.first = _act_and_advance(self.states, self.live, self.log, self.used,
                                              env.params, self.holds, self.first, *compiled)
        self._settle(status, _NO_ACTIONS)

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
        self.states["cur"] -= m

    def to_rollout(self) -> Rollout:
        """The recorded decisions, once every episode has ended."""
        e, n = len(self.states), self.env.n_agents
        d = self.first
        # every UAV observes at time 0, so every (episode, agent) path has a decision
        path_start = np.zeros(e * n + 1, np.int64)
        np.cumsum(self.states["n_dec"].reshape(-1), out=path_start[1:])
        obs, time = np.empty((d, self.env.obs_dim)), np.empty(d)
        actions, rewards, durations = np.empty(d, np.int64), np.empty(d), np.empty(d)
        _paths(self.log[:d], path_start, n, obs, actions, rewards, durations, time)
        return Rollout(
            obs=obs, actions=actions, rewards=rewards, durations=durations, path_start=path_start,
            path_episode=np.repeat(np.arange(e, dtype=np.int64), n),
            path_agent=np.tile(np.arange(n, dtype=np.int64), e),
            episode_return=self.states["returns"].mean(axis=1),
            truncated=self.states["truncated"].copy(),
            info={"decision_time": time, "end_time": self.states["t_end"].copy(),
                  "events": self.states["events"].copy()})


class WildfireEnv:
    """docs/semantics.md section 3, fast: implements :class:`repro.core.rollout.BatchEnv`."""

    name = "wildfire"

    def __init__(self, cfg: WildfireConfig):
        cfg.validate()
        self.cfg = cfg
        self.obs_dim = cfg.obs_dim
        self.n_actions = cfg.n_actions
        self.n_agents = cfg.n_agents
        self.gamma = cfg.gamma
        self.params = params_record(cfg)
        self.state_dtype = state_dtype(cfg)
        self.log_dtype = log_dtype(cfg.obs_dim)

    def rollout(self, policy: Policy, n_episodes: int,
                seed: int | np.random.SeedSequence) -> Rollout:
        return self.simulate(policy, draw_episodes(self.cfg, n_episodes, seed))

    def simulate(self, policy: Policy, draws: EpisodeDraws) -> Rollout:
        """Run the episodes of ``draws`` (tests script start positions and hold durations): one
        policy call per round; the kernel itself acts on small rounds for a compiled policy."""
        batch = WildfireBatch(self, draws)
        compiled = getattr(policy, "compiled", None)
        if compiled is not None and compiled.n_actions != self.n_actions:
            compiled = None  # the policy's call will meet the range check, and report it
        while (n := batch.n_pending) > 0:
            if compiled is not None and n <= MAX_ROWS:
                batch.act_compiled(compiled)
            else:
                batch.act(policy(batch.pending()))
        return batch.to_rollout()
