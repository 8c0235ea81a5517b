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

# Every kernel works on preallocated arrays only. Without the runtime's reference counting
# (_nrt=False; nothing is allocated inside), passing the state tuple to a helper costs nothing,
# whereas counting references to its ~35 arrays made each helper call cost ~0.5 us.
jit = njit(cache=True, _nrt=False)

fs_delay_nb = jit(fs_delay)

Params = namedtuple("Params", "n_agents n_fires n_obs v dt latency tol gamma r_ext r_pen "
                              "t_health t_max q1 q2 fires")
State = namedtuple("State", [
    "now", "done", "t_end", "n_alive", "events",  # (B,) per episode
    "pos", "origin", "goal", "t_dep", "length", "flying",  # (B, N, ...) UAV motion
    "interest", "attacking", "in_party", "n_holds", "holds", "rank", "cur", "n_dec", "uwait",
    "returns",  # (B, N, ...) UAV bookkeeping
    "alive", "health", "t_update", "party", "fwait",  # (B, K) fires
    "ht", "hp", "hs", "hk", "hw", "hn", "seq",  # event heap (B, CAP) and its size, next sequence
    "n_rows",  # (2,) rows used in the log, rows already handed to the policy
])
Log = namedtuple("Log", "obs act rew dur time ep agent idx")


# --- event heap ----------------------------------------------------------------------------------

@jit
def _before(s, e, a, b):
    if s.ht[e, a] != s.ht[e, b]:
        return s.ht[e, a] < s.ht[e, b]
    if s.hp[e, a] != s.hp[e, b]:
        return s.hp[e, a] < s.hp[e, b]
    return s.hs[e, a] < s.hs[e, b]


@jit
def _swap(s, e, a, b):
    s.ht[e, a], s.ht[e, b] = s.ht[e, b], s.ht[e, a]
    s.hp[e, a], s.hp[e, b] = s.hp[e, b], s.hp[e, a]
    s.hs[e, a], s.hs[e, b] = s.hs[e, b], s.hs[e, a]
    s.hk[e, a], s.hk[e, b] = s.hk[e, b], s.hk[e, a]
    s.hw[e, a], s.hw[e, b] = s.hw[e, b], s.hw[e, a]


@jit
def _push(s, e, delay, prio, kind, who):
    """Schedule an event ``delay`` after now (SimPy: time now + delay); return its sequence."""
    n = s.hn[e]
    s.ht[e, n] = s.now[e] + delay
    s.hp[e, n] = prio
    s.hs[e, n] = s.seq[e]
    s.hk[e, n] = kind
    s.hw[e, n] = who
    s.seq[e] += 1
    s.hn[e] = n + 1
    while n > 0:
        parent = (n - 1) // 2
        if not _before(s, e, n, parent):
            break
        _swap(s, e, n, parent)
        n = parent
    return s.seq[e] - 1


@jit
def _pop(s, e):
    """Remove the first event and return (time, sequence, kind, who)."""
    t, sq, kind, who = s.ht[e, 0], s.hs[e, 0], s.hk[e, 0], s.hw[e, 0]
    n = s.hn[e] - 1
    s.hn[e] = n
    if n > 0:
        _swap(s, e, 0, n)
        i = 0
        while True:
            left, best = 2 * i + 1, i
            if left < n and _before(s, e, left, best):
                best = left
            if left + 1 < n and _before(s, e, left + 1, best):
                best = left + 1
            if best == i:
                break
            _swap(s, e, i, best)
            i = best
    return t, sq, kind, who


# --- model (mirrors reference.WildfireModel method by method) ------------------------------------

@jit
def _dist(ax, ay, bx, by):
    return math.sqrt((bx - ax) * (bx - ax) + (by - ay) * (by - ay))


@jit
def _health_now(s, e, j):
    if not s.alive[e, j]:
        return 0.0
    return max(0.0, s.health[e, j] - s.party[e, j] * (s.now[e] - s.t_update[e, j]))


@jit
def _observe(s, lg, p, e, i):
    now = s.now[e]
    prev = s.cur[e, i]
    sojourn = 0.0
    if prev >= 0:
        sojourn = now - lg.time[prev]
        lg.dur[prev] = sojourn
    row = s.n_rows[0]
    s.n_rows[0] = row + 1
    x, y = s.pos[e, i, 0], s.pos[e, i, 1]
    o = lg.obs[row]
    o[0], o[1] = x, y
    prev_d, prev_j = -1.0, -1
    for r in range(p.n_obs):  # next in (distance, index) order: the lower index wins ties
        best, best_d = -1, np.inf
        for j in range(p.n_fires):
            d = _dist(x, y, p.fires[j, 0], p.fires[j, 1])
            after = d > prev_d or (d == prev_d and j > prev_j)
            if after and d < best_d:
                best, best_d = j, d
        prev_d, prev_j = best_d, best
        s.rank[e, i, r] = best
        interested = 0
        for a in range(p.n_agents):
            if s.interest[e, a] == best:
                interested += 1
        base = 2 + OBS_PER_FIRE * r
        o[base] = best_d
        o[base + 1] = 1.0
        o[base + 2] = interested
        o[base + 3] = 1.0 if s.alive[e, best] else 0.0
        o[base + 4] = _health_now(s, e, best)
    o[2 + OBS_PER_FIRE * p.n_obs] = sojourn
    lg.act[row] = -1
    lg.rew[row] = 0.0
    lg.dur[row] = np.nan
    lg.time[row] = now
    lg.ep[row] = e
    lg.agent[row] = i
    lg.idx[row] = s.n_dec[e, i]
    s.n_dec[e, i] += 1
    s.cur[e, i] = row
    s.uwait[e, i] = _push(s, e, p.latency, NORMAL, LATENCY, i)


@jit
def _accrue(s, lg, p, e, i, r):
    row = s.cur[e, i]
    lg.rew[row] += math.exp(-p.gamma * (s.now[e] - lg.time[row])) * r
    s.returns[e, i] += r


@jit
def _party_change(s, p, e, j, delta):
    if not s.alive[e, j]:
        return
    now = s.now[e]
    s.health[e, j] = s.health[e, j] - s.party[e, j] * (now - s.t_update[e, j])
    s.t_update[e, j] = now
    s.party[e, j] += delta
    _push(s, e, 0.0, URGENT, INT_FIRE, j)


@jit
def _penalise(s, lg, p, e, j):
    if s.party[e, j] < 2:
        return
    for i in range(p.n_agents):
        member = s.in_party[e, i] and s.attacking[e, i] == j
        if member or not p.q2:
            _accrue(s, lg, p, e, i, p.r_pen)


@jit
def _start_action(s, lg, p, e, i):
    now = s.now[e]
    a = lg.act[s.cur[e, i]]
    s.interest[e, i] = -1
    if a < p.n_obs:
        target = s.rank[e, i, a]
        s.interest[e, i] = target
        if s.in_party[e, i]:
            s.in_party[e, i] = False
            _party_change(s, p, e, s.attacking[e, i], -1)
        if not p.q1:
            s.attacking[e, i] = -1
        ox, oy = s.pos[e, i, 0], s.pos[e, i, 1]
        gx, gy = p.fires[target, 0], p.fires[target, 1]
        length = _dist(ox, oy, gx, gy)
        s.origin[e, i, 0], s.origin[e, i, 1] = ox, oy
        s.goal[e, i, 0], s.goal[e, i, 1] = gx, gy
        s.t_dep[e, i] = now
        s.length[e, i] = length
        s.flying[e, i] = True
        d = fs_delay_nb(now, length / p.v, p.dt)
    else:
        x, y = s.pos[e, i, 0], s.pos[e, i, 1]
        for j in range(p.n_fires):
            if _dist(x, y, p.fires[j, 0], p.fires[j, 1]) < p.tol:
                s.interest[e, i] = j
                if s.attacking[e, i] != j:
                    s.attacking[e, i] = j
                    if s.alive[e, j]:
                        s.in_party[e, i] = True
                        _party_change(s, p, e, j, 1)
                        _penalise(s, lg, p, e, j)
                break
        size = s.holds.shape[2]
        hold = s.holds[e, i, s.n_holds[e, i] % size]
        s.n_holds[e, i] += 1
        d = fs_delay_nb(now, hold, p.dt)
    s.uwait[e, i] = _push(s, e, d, NORMAL, ACTION, i)


@jit
def _land(s, p, e, i, cut):
    if not s.flying[e, i]:
        return
    length = s.length[e, i]
    if cut and length > 0:
        frac = min(1.0, p.v * (s.now[e] - s.t_dep[e, i]) / length)
        for c in range(2):
            s.pos[e, i, c] = s.origin[e, i, c] + frac * (s.goal[e, i, c] - s.origin[e, i, c])
    else:
        s.pos[e, i, 0], s.pos[e, i, 1] = s.goal[e, i, 0], s.goal[e, i, 1]
    s.flying[e, i] = False


@jit
def _replan(s, p, e, j):
    if s.party[e, j] == 0:
        s.fwait[e, j] = -1  # idle until the party changes
    else:
        d = fs_delay_nb(s.now[e], s.health[e, j] / s.party[e, j], p.dt)
        s.fwait[e, j] = _push(s, e, d, NORMAL, EXTINGUISH, j)


@jit
def _end(s, lg, p, e):
    s.done[e] = True
    s.t_end[e] = s.now[e]
    for i in range(p.n_agents):
        row = s.cur[e, i]
        lg.dur[row] = s.t_end[e] - lg.time[row]


@jit
def _extinguish(s, lg, p, e, j):
    s.alive[e, j] = False
    s.n_alive[e] -= 1
    for i in range(p.n_agents):
        _accrue(s, lg, p, e, i, p.r_ext)
    for i in range(p.n_agents):
        if s.interest[e, i] == j:
            _push(s, e, 0.0, URGENT, INT_UAV, i)
    if s.n_alive[e] == 0:
        _end(s, lg, p, e)


# --- kernels -------------------------------------------------------------------------------------

@jit
def _setup(s, lg, p):
    """Time 0: every UAV observes (in index order), then the T_max clock starts."""
    for e in range(s.now.shape[0]):
        for i in range(p.n_agents):
            _observe(s, lg, p, e, i)
        _push(s, e, p.t_max, NORMAL, CLOCK, 0)


@jit
def _advance(s, lg, p, pending):
    """Run every live episode until it is blocked or over; list the rows awaiting an action."""
    log_capacity = lg.act.shape[0]
    heap_capacity = s.ht.shape[1]
    for e in range(s.now.shape[0]):
        while not s.done[e]:
            kind, who, sq = s.hk[e, 0], s.hw[e, 0], s.hs[e, 0]
            if kind == LATENCY and sq == s.uwait[e, who] and lg.act[s.cur[e, who]] < 0:
                break  # the policy has not decided yet
            if s.n_rows[0] >= log_capacity:
                return GROW_LOG, 0
            if s.hn[e] + p.n_agents + 2 > heap_capacity:
                return HEAP_FULL, 0
            t, sq, kind, who = _pop(s, e)
            s.now[e] = t
            s.events[e] += 1
            if kind == LATENCY:
                if sq == s.uwait[e, who]:
                    _start_action(s, lg, p, e, who)
            elif kind == ACTION:
                if sq == s.uwait[e, who]:
                    _land(s, p, e, who, False)
                    _observe(s, lg, p, e, who)
            elif kind == INT_UAV:
                _land(s, p, e, who, True)
                _observe(s, lg, p, e, who)
            elif kind == EXTINGUISH:
                if sq == s.fwait[e, who]:
                    _extinguish(s, lg, p, e, who)
            elif kind == INT_FIRE:
                if s.alive[e, who]:
                    _replan(s, p, e, who)
            else:
                _end(s, lg, p, e)
    # Every new row, including decisions superseded at once (interrupted within their latency),
    # which the dynamics never needed but the rollout records; the caller answers them all.
    n = 0
    for row in range(s.n_rows[1], s.n_rows[0]):
        if lg.act[row] < 0:
            pending[n] = row
            n += 1
    s.n_rows[1] = s.n_rows[0]
    return OK, n


# --- Python side ---------------------------------------------------------------------------------

def _new_log(capacity: int, obs_dim: int) -> Log:
    return Log(obs=np.empty((capacity, obs_dim)), act=np.full(capacity, -1, dtype=np.int64),
               rew=np.zeros(capacity), dur=np.full(capacity, np.nan), time=np.zeros(capacity),
               ep=np.zeros(capacity, dtype=np.int64), agent=np.zeros(capacity, dtype=np.int64),
               idx=np.zeros(capacity, dtype=np.int64))


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
        fires = fire_positions(cfg)
        self.params = Params(
            n_agents=cfg.n_agents, n_fires=len(fires), n_obs=cfg.n_observed, v=cfg.v_uav,
            dt=cfg.dt or 0.0, latency=cfg.decision_latency, tol=cfg.at_fire_tol, gamma=cfg.gamma,
            r_ext=cfg.r_ext, r_pen=cfg.r_pen, t_health=cfg.t_health, t_max=cfg.t_max,
            q1=cfg.quirk_q1_stale_attack, q2=cfg.quirk_q2_penalty_party_only, fires=fires)

    def rollout(self, policy: Policy, n_episodes: int,
                seed: int | np.random.SeedSequence) -> Rollout:
        return self.simulate(policy, draw_episodes(self.cfg, n_episodes, seed))

    def simulate(self, policy: Policy, draws: EpisodeDraws) -> Rollout:
        """Run the episodes of ``draws`` (tests script start positions and hold durations)."""
        p, b = self.params, draws.n_episodes
        s = self._initial_state(draws)
        lg = _new_log(max(1024, 64 * b * p.n_agents), self.obs_dim)
        _setup(s, lg, p)
        pending = np.empty(len(lg.act), dtype=np.int64)
        while True:
            status, n = _advance(s, lg, p, pending)
            if status == GROW_LOG:
                lg = _grow(lg)
                pending = np.empty(len(lg.act), dtype=np.int64)
                continue
            if status == HEAP_FULL:
                raise RuntimeError(f"event heap of {HEAP_CAPACITY} entries is full")
            if n == 0:
                break
            rows = pending[:n]
            batch = DecisionBatch(obs=lg.obs[rows], episode=lg.ep[rows], agent=lg.agent[rows],
                                  index=lg.idx[rows])
            lg.act[rows] = check_actions(policy(batch), n, self.n_actions)
        used = s.n_rows[0]
        return rollout_from_records(
            episode=lg.ep[:used], agent=lg.agent[:used], index=lg.idx[:used],
            time=lg.time[:used], obs=lg.obs[:used], actions=lg.act[:used], rewards=lg.rew[:used],
            durations=lg.dur[:used], agent_returns=s.returns, end_time=s.t_end, events=s.events)

    def _initial_state(self, draws: EpisodeDraws) -> State:
        p, b = self.params, draws.n_episodes
        n, k = p.n_agents, p.n_fires

        def full(shape, value, dtype=np.float64):
            return np.full(shape, value, dtype=dtype)

        return State(
            now=full(b, 0.0), done=full(b, False, np.bool_), t_end=full(b, np.nan),
            n_alive=full(b, k, np.int64), events=full(b, 0, np.int64),
            pos=draws.starts.astype(np.float64, copy=True), origin=full((b, n, 2), 0.0),
            goal=full((b, n, 2), 0.0), t_dep=full((b, n), 0.0), length=full((b, n), 0.0),
            flying=full((b, n), False, np.bool_), interest=full((b, n), -1, np.int64),
            attacking=full((b, n), -1, np.int64), in_party=full((b, n), False, np.bool_),
            n_holds=full((b, n), 0, np.int64), holds=np.ascontiguousarray(draws.holds, np.float64),
            rank=full((b, n, p.n_obs), -1, np.int64), cur=full((b, n), -1, np.int64),
            n_dec=full((b, n), 0, np.int64), uwait=full((b, n), -1, np.int64),
            returns=full((b, n), 0.0), alive=full((b, k), True, np.bool_),
            health=full((b, k), p.t_health), t_update=full((b, k), 0.0),
            party=full((b, k), 0, np.int64), fwait=full((b, k), -1, np.int64),
            ht=full((b, HEAP_CAPACITY), 0.0), hp=full((b, HEAP_CAPACITY), 0, np.int64),
            hs=full((b, HEAP_CAPACITY), 0, np.int64), hk=full((b, HEAP_CAPACITY), 0, np.int64),
            hw=full((b, HEAP_CAPACITY), 0, np.int64), hn=full(b, 0, np.int64),
            seq=full(b, 0, np.int64), n_rows=full(2, 0, np.int64))
