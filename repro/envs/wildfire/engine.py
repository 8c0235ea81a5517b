"""The fast wildfire engine: a batch of episodes in numba, one policy call per round.

Each episode keeps an array heap of pending events keyed exactly like SimPy's queue, (time,
priority, sequence number) with interrupts (URGENT) before timeouts (NORMAL) at the same instant,
and schedules the same events in the same order as :mod:`repro.envs.wildfire.reference`. Hence
same-instant events, which FS simulation makes common, are processed in the reference's order.
An event that a process no longer waits for (its wait was interrupted, or its fire re-planned) is
stale and skipped, as SimPy skips a triggered event without callbacks.

``_advance`` runs every live episode until it is blocked (its next event is the end of a decision
latency whose action the policy has not given yet) or over. Python then hands all pending
observations of the batch to the policy in ONE call, writes the actions back, and repeats.
Decisions are appended to a flat log and sorted into contiguous paths at the end.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from repro.core.rollout import DecisionBatch, Policy, Rollout
from repro.envs.wildfire.params import (OBS_PER_FIRE, EpisodeDraws, WildfireConfig, draw_episodes,
                                        fire_positions, fs_delay)
from repro.envs.wildfire.records import rollout_from_records
from repro.envs.wildfire.reference import check_actions

URGENT, NORMAL = 0, 1
"""SimPy's priorities: an interrupt at time t comes before any timeout at t."""
LATENCY, ACTION, EXTINGUISH, INT_UAV, INT_FIRE, CLOCK = range(6)
"""Event kinds: decision latency over, macro-action over, fire out, UAV interrupted (its fire
went out), fire interrupted (its party changed), T_max reached."""
OK, GROW_LOG, HEAP_FULL = range(3)
"""Status codes of ``_advance``."""
HEAP_CAPACITY = 128
"""Pending events per episode: live waits (N UAVs, 9 fires, the clock) plus stale ones."""

# An episode's whole state is one numpy record (a row of a structured array), and so are the
# parameters: numba passes a record to a helper as a bare pointer, whereas a tuple of arrays costs a
# reference count update per array and call. Flags inside records are int8 (numba does not support
# nested boolean arrays).
jit = njit(cache=True)

fs_delay_nb = jit(fs_delay)


def params_record(cfg: WildfireConfig) -> np.ndarray:
    """The (1,) structured array of the kernels' parameters."""
    fires = fire_positions(cfg)
    rec = np.zeros(1, np.dtype([
        ("n_agents", np.int64), ("n_fires", np.int64), ("n_obs", np.int64), ("v", np.float64),
        ("dt", np.float64), ("latency", np.float64), ("tol", np.float64), ("gamma", np.float64),
        ("r_ext", np.float64), ("r_pen", np.float64), ("t_health", np.float64),
        ("t_max", np.float64), ("q1", np.bool_), ("q2", np.bool_),
        ("fires", np.float64, fires.shape)], align=True))
    rec[0] = (cfg.n_agents, len(fires), cfg.n_observed, cfg.v_uav, cfg.dt or 0.0,
              cfg.decision_latency, cfg.at_fire_tol, cfg.gamma, cfg.r_ext, cfg.r_pen,
              cfg.t_health, cfg.t_max, cfg.quirk_q1_stale_attack, cfg.quirk_q2_penalty_party_only,
              fires)
    return rec


def state_dtype(cfg: WildfireConfig) -> np.dtype:
    """One episode's state: scalars, then (N, ...) UAV fields, (K,) fire fields, the event heap."""
    n, k, f8, i8, i1 = cfg.n_agents, len(fire_positions(cfg)), np.float64, np.int64, np.int8
    return np.dtype([
        ("now", f8), ("done", np.bool_), ("t_end", f8), ("n_alive", i8), ("events", i8),
        # UAV motion
        ("pos", f8, (n, 2)), ("origin", f8, (n, 2)), ("goal", f8, (n, 2)), ("t_dep", f8, n),
        ("length", f8, n), ("flying", i1, n),
        # UAV bookkeeping
        ("interest", i8, n), ("attacking", i8, n), ("in_party", i1, n), ("n_holds", i8, n),
        ("holds", f8, (n, cfg.hold_table_size)), ("rank", i8, (n, cfg.n_observed)),
        ("cur", i8, n), ("n_dec", i8, n), ("uwait", i8, n), ("returns", f8, n),
        # fires
        ("alive", i1, k), ("health", f8, k), ("t_update", f8, k), ("party", i8, k),
        ("fwait", i8, k),
        # scratch of an observation: the observing UAV's distance to every fire, computed once
        # per observation rather than once per observed rank
        ("fire_dist", f8, k),
        # event heap: time, priority, sequence number, kind, who (narrow types: a smaller record
        # stays in cache longer); its size; the next sequence
        ("ht", f8, HEAP_CAPACITY), ("hp", i1, HEAP_CAPACITY), ("hs", i8, HEAP_CAPACITY),
        ("hk", i1, HEAP_CAPACITY), ("hw", np.int32, HEAP_CAPACITY), ("hn", i8), ("seq", i8),
    ], align=True)


Log = namedtuple("Log", "obs act rew dur time ep agent idx used")
"""One row per decision, in the order they were observed; ``used[0]`` rows are filled."""


# --- event heap ----------------------------------------------------------------------------------

@jit
def _before(s, a, b):
    if s.ht[a] != s.ht[b]:
        return s.ht[a] < s.ht[b]
    if s.hp[a] != s.hp[b]:
        return s.hp[a] < s.hp[b]
    return s.hs[a] < s.hs[b]


@jit
def _swap(s, a, b):
    s.ht[a], s.ht[b] = s.ht[b], s.ht[a]
    s.hp[a], s.hp[b] = s.hp[b], s.hp[a]
    s.hs[a], s.hs[b] = s.hs[b], s.hs[a]
    s.hk[a], s.hk[b] = s.hk[b], s.hk[a]
    s.hw[a], s.hw[b] = s.hw[b], s.hw[a]


@jit
def _push(s, delay, prio, kind, who):
    """Schedule an event ``delay`` after now (SimPy: time now + delay); return its sequence."""
    n = s.hn
    s.ht[n] = s.now + delay
    s.hp[n] = prio
    s.hs[n] = s.seq
    s.hk[n] = kind
    s.hw[n] = who
    s.seq += 1
    s.hn = n + 1
    while n > 0:
        parent = (n - 1) // 2
        if not _before(s, n, parent):
            break
        _swap(s, n, parent)
        n = parent
    return s.seq - 1


@jit
def _pop(s):
    """Remove the first event and return (time, sequence, kind, who)."""
    t, sq, kind, who = s.ht[0], s.hs[0], s.hk[0], s.hw[0]
    n = s.hn - 1
    s.hn = n
    if n > 0:
        _swap(s, 0, n)
        i = 0
        while True:
            left, best = 2 * i + 1, i
            if left < n and _before(s, left, best):
                best = left
            if left + 1 < n and _before(s, left + 1, best):
                best = left + 1
            if best == i:
                break
            _swap(s, i, best)
            i = best
    return t, sq, kind, who


# --- model (mirrors reference.WildfireModel method by method) ------------------------------------

@jit
def _dist(ax, ay, bx, by):
    return math.sqrt((bx - ax) * (bx - ax) + (by - ay) * (by - ay))


@jit
def _health_now(s, j):
    if not s.alive[j]:
        return 0.0
    return max(0.0, s.health[j] - s.party[j] * (s.now - s.t_update[j]))


@jit
def _observe(s, lg, p, e, i):
    now = s.now
    prev = s.cur[i]
    sojourn = 0.0
    if prev >= 0:
        sojourn = now - lg.time[prev]
        lg.dur[prev] = sojourn
    row = lg.used[0]
    lg.used[0] = row + 1
    x, y = s.pos[i, 0], s.pos[i, 1]
    o = lg.obs[row]
    o[0], o[1] = x, y
    dist = s.fire_dist
    for j in range(p.n_fires):
        dist[j] = _dist(x, y, p.fires[j, 0], p.fires[j, 1])
    prev_d, prev_j = -1.0, -1
    for r in range(p.n_obs):  # next in (distance, index) order: the lower index wins ties
        best, best_d = -1, np.inf
        for j in range(p.n_fires):
            d = dist[j]
            after = d > prev_d or (d == prev_d and j > prev_j)
            if after and d < best_d:
                best, best_d = j, d
        prev_d, prev_j = best_d, best
        s.rank[i, r] = best
        interested = 0
        for a in range(p.n_agents):
            if s.interest[a] == best:
                interested += 1
        base = 2 + OBS_PER_FIRE * r
        o[base] = best_d
        o[base + 1] = 1.0
        o[base + 2] = interested
        o[base + 3] = 1.0 if s.alive[best] else 0.0
        o[base + 4] = _health_now(s, best)
    o[2 + OBS_PER_FIRE * p.n_obs] = sojourn
    lg.act[row] = -1
    lg.rew[row] = 0.0
    lg.dur[row] = np.nan
    lg.time[row] = now
    lg.ep[row] = e
    lg.agent[row] = i
    lg.idx[row] = s.n_dec[i]
    s.n_dec[i] += 1
    s.cur[i] = row
    s.uwait[i] = _push(s, p.latency, NORMAL, LATENCY, i)


@jit
def _accrue(s, lg, p, i, r):
    row = s.cur[i]
    lg.rew[row] += math.exp(-p.gamma * (s.now - lg.time[row])) * r
    s.returns[i] += r


@jit
def _party_change(s, p, j, delta):
    if not s.alive[j]:
        return
    now = s.now
    s.health[j] = s.health[j] - s.party[j] * (now - s.t_update[j])
    s.t_update[j] = now
    s.party[j] += delta
    _push(s, 0.0, URGENT, INT_FIRE, j)


@jit
def _penalise(s, lg, p, j):
    if s.party[j] < 2:
        return
    for i in range(p.n_agents):
        member = s.in_party[i] and s.attacking[i] == j
        if member or not p.q2:
            _accrue(s, lg, p, i, p.r_pen)


@jit
def _start_action(s, lg, p, i):
    now = s.now
    a = lg.act[s.cur[i]]
    s.interest[i] = -1
    if a < p.n_obs:
        target = s.rank[i, a]
        s.interest[i] = target
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
        d = fs_delay_nb(now, length / p.v, p.dt)
    else:
        x, y = s.pos[i, 0], s.pos[i, 1]
        for j in range(p.n_fires):
            if _dist(x, y, p.fires[j, 0], p.fires[j, 1]) < p.tol:
                s.interest[i] = j
                if s.attacking[i] != j:
                    s.attacking[i] = j
                    if s.alive[j]:
                        s.in_party[i] = True
                        _party_change(s, p, j, 1)
                        _penalise(s, lg, p, j)
                break
        size = s.holds.shape[1]
        hold = s.holds[i, s.n_holds[i] % size]
        s.n_holds[i] += 1
        d = fs_delay_nb(now, hold, p.dt)
    s.uwait[i] = _push(s, d, NORMAL, ACTION, i)


@jit
def _land(s, p, i, cut):
    if not s.flying[i]:
        return
    length = s.length[i]
    if cut and length > 0:
        frac = min(1.0, p.v * (s.now - s.t_dep[i]) / length)
        for c in range(2):
            s.pos[i, c] = s.origin[i, c] + frac * (s.goal[i, c] - s.origin[i, c])
    else:
        s.pos[i, 0], s.pos[i, 1] = s.goal[i, 0], s.goal[i, 1]
    s.flying[i] = False


@jit
def _replan(s, p, j):
    if s.party[j] == 0:
        s.fwait[j] = -1  # idle until the party changes
    else:
        d = fs_delay_nb(s.now, s.health[j] / s.party[j], p.dt)
        s.fwait[j] = _push(s, d, NORMAL, EXTINGUISH, j)


@jit
def _end(s, lg, p):
    s.done = True
    s.t_end = s.now
    for i in range(p.n_agents):
        row = s.cur[i]
        lg.dur[row] = s.t_end - lg.time[row]


@jit
def _extinguish(s, lg, p, j):
    s.alive[j] = False
    s.n_alive -= 1
    for i in range(p.n_agents):
        _accrue(s, lg, p, i, p.r_ext)
    for i in range(p.n_agents):
        if s.interest[i] == j:
            _push(s, 0.0, URGENT, INT_UAV, i)
    if s.n_alive == 0:
        _end(s, lg, p)


# --- kernels -------------------------------------------------------------------------------------

@jit
def _setup(states, lg, params):
    """Time 0: every UAV observes (in index order), then the T_max clock starts."""
    p = params[0]
    for e in range(len(states)):
        s = states[e]
        for i in range(p.n_agents):
            _observe(s, lg, p, e, i)
        _push(s, p.t_max, NORMAL, CLOCK, 0)


@jit
def _advance(states, lg, params):
    """Run every live episode until it is blocked (its next event is the end of a decision latency
    whose action is still -1) or over, or until the log or a heap is full (the status says)."""
    p = params[0]
    for e in range(len(states)):
        s = states[e]
        while not s.done:
            kind, who, sq = s.hk[0], s.hw[0], s.hs[0]
            if kind == LATENCY and sq == s.uwait[who] and lg.act[s.cur[who]] < 0:
                break  # the policy has not decided yet
            if lg.used[0] >= len(lg.act):
                return GROW_LOG
            if s.hn + p.n_agents + 2 > len(s.ht):
                return HEAP_FULL
            t, sq, kind, who = _pop(s)
            s.now = t
            s.events += 1
            if kind == LATENCY:
                if sq == s.uwait[who]:
                    _start_action(s, lg, p, who)
            elif kind == ACTION:
                if sq == s.uwait[who]:
                    _land(s, p, who, False)
                    _observe(s, lg, p, e, who)
            elif kind == INT_UAV:
                _land(s, p, who, True)
                _observe(s, lg, p, e, who)
            elif kind == EXTINGUISH:
                if sq == s.fwait[who]:
                    _extinguish(s, lg, p, who)
            elif kind == INT_FIRE:
                if s.alive[who]:
                    _replan(s, p, who)
            else:
                _end(s, lg, p)
    return OK


# --- Python side ---------------------------------------------------------------------------------

def _new_log(capacity: int, obs_dim: int) -> Log:
    """Uninitialised: ``_observe`` writes every field of a row."""
    return Log(obs=np.empty((capacity, obs_dim)), act=np.empty(capacity, dtype=np.int64),
               rew=np.empty(capacity), dur=np.empty(capacity), time=np.empty(capacity),
               ep=np.empty(capacity, dtype=np.int64), agent=np.empty(capacity, dtype=np.int64),
               idx=np.empty(capacity, dtype=np.int64), used=np.zeros(1, dtype=np.int64))


def _grow(lg: Log) -> Log:
    bigger = _new_log(2 * len(lg.act), lg.obs.shape[1])
    for old, new in zip(lg, bigger):
        new[:len(old)] = old
    return bigger


class WildfireEnv:
    """SPEC section 3, fast: implements :class:`repro.core.rollout.BatchEnv`."""

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

    def rollout(self, policy: Policy, n_episodes: int,
                seed: int | np.random.SeedSequence) -> Rollout:
        return self.simulate(policy, draw_episodes(self.cfg, n_episodes, seed))

    def simulate(self, policy: Policy, draws: EpisodeDraws) -> Rollout:
        """Run the episodes of ``draws`` (tests script start positions and hold durations)."""
        states = self._initial_states(draws)
        lg = _new_log(max(1024, 64 * draws.n_episodes * self.n_agents), self.obs_dim)
        _setup(states, lg, self.params)
        # A round's new rows are contiguous; all of them await an action, including decisions
        # superseded at once (interrupted within their latency), which the dynamics never needed
        # but the rollout records. So the policy reads views of the log: no gathering.
        first = 0
        while True:
            status = _advance(states, lg, self.params)
            if status == GROW_LOG:
                lg = _grow(lg)
                continue
            if status == HEAP_FULL:
                raise RuntimeError(f"event heap of {HEAP_CAPACITY} entries is full")
            end = int(lg.used[0])
            if end == first:
                break
            rows = slice(first, end)
            batch = DecisionBatch(obs=lg.obs[rows], episode=lg.ep[rows], agent=lg.agent[rows],
                                  index=lg.idx[rows])
            lg.act[rows] = check_actions(policy(batch), end - first, self.n_actions)
            first = end
        used = slice(0, first)
        return rollout_from_records(
            episode=lg.ep[used], agent=lg.agent[used], index=lg.idx[used], time=lg.time[used],
            obs=lg.obs[used], actions=lg.act[used], rewards=lg.rew[used],
            durations=lg.dur[used], agent_returns=states["returns"].copy(),
            end_time=states["t_end"].copy(), events=states["events"].copy())

    def _initial_states(self, draws: EpisodeDraws) -> np.ndarray:
        cfg = self.cfg
        states = np.zeros(draws.n_episodes, self.state_dtype)
        states["t_end"] = np.nan
        states["n_alive"] = self.params["n_fires"][0]
        states["pos"] = draws.starts
        states["holds"] = draws.holds
        for field in ("interest", "attacking", "rank", "cur", "uwait", "fwait"):
            states[field] = -1
        states["alive"] = 1
        states["health"] = cfg.t_health
        return states
