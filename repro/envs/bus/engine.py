"""The fast bus engine: a numba kernel that advances a whole batch of episodes between policy calls.

It is an exact transcription of the SimPy reference (``reference.py``), event by event. SimPy keeps
a heap keyed by (time, priority, insertion id) and processes the smallest key first; this engine
keeps the same keys in a small array per episode (at most a few events per bus are ever scheduled,
so a linear scan for the minimum beats a heap) and schedules exactly the events SimPy schedules, in
the same order:

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
"""

from __future__ import annotations

from typing import Any

import numba as nb
import numpy as np

from repro.core.errors import require
from repro.core.rollout import DecisionBatch, Policy, Rollout
from repro.envs.bus.params import BusConfig

OBS_DIM = 4
"""Observation: [stop index (0-based), headway h (min), load at arrival (pax), sojourn time (s)]."""

URGENT, NORMAL = 0, 1  # SimPy's event priorities
INIT, GRANT, DECISION, DWELL, RELEASE, TRAVEL = range(6)


@nb.njit(cache=True)
def _push(ev_time, ev_prio, ev_id, ev_kind, ev_arg, next_id, e, t, prio, kind, arg):
    slot = 0
    while ev_kind[e, slot] >= 0:
        slot += 1
    ev_time[e, slot] = t
    ev_prio[e, slot] = prio
    ev_id[e, slot] = next_id[e]
    ev_kind[e, slot] = kind
    ev_arg[e, slot] = arg
    next_id[e] += 1


@nb.njit(cache=True)
def _peek(ev_time, ev_prio, ev_id, ev_kind, e):
    """Slot of the smallest (time, priority, id) key, or -1 when nothing is scheduled."""
    best = -1
    for s in range(ev_kind.shape[1]):
        if ev_kind[e, s] < 0:
            continue
        if best < 0:
            best = s
            continue
        if ev_time[e, s] < ev_time[e, best] or (ev_time[e, s] == ev_time[e, best] and (
                ev_prio[e, s] < ev_prio[e, best] or (
                    ev_prio[e, s] == ev_prio[e, best] and ev_id[e, s] < ev_id[e, best]))):
            best = s
    return best


@nb.njit(cache=True)
def _advance(actions, act_offset,
             # configuration
             n_actions, alight, rate, l_max, rt, t_a, t_b, headway, t_hold, gamma, horizon,
             # per-episode state
             now, done, ep_return, next_id, ev_time, ev_prio, ev_id, ev_kind, ev_arg,
             bus_stop, bus_load, bus_anchor, bus_buffer, bus_ndec, bus_arr,
             stop_busy, stop_last_dep, queue, q_head, q_len, pending, n_pending,
             dec_obs, dec_act, dec_rew, dec_dur,
             arr_time, arr_bus, arr_stop, arr_h, arr_load, arr_u, arr_b, n_arr):
    """Deliver the actions of the pending decisions, then run every episode until it is blocked.

    ``actions[act_offset[e]:act_offset[e] + n_pending[e]]`` answer episode e's pending buses in
    order. Returns False if an action is out of range (nothing is changed then).
    """
    n_ep, n_bus = bus_stop.shape
    n_stop = stop_busy.shape[1]
    for i in range(actions.shape[0]):
        if actions[i] < 0 or actions[i] >= n_actions:
            return False
    for e in range(n_ep):
        if done[e]:
            continue
        for p in range(n_pending[e]):
            b = pending[e, p]
            dec_act[e, b, bus_ndec[e, b] - 1] = actions[act_offset[e] + p]
            _push(ev_time, ev_prio, ev_id, ev_kind, ev_arg, next_id, e, now[e], NORMAL, DECISION, b)
        n_pending[e] = 0
        while True:
            s = _peek(ev_time, ev_prio, ev_id, ev_kind, e)
            if n_pending[e] > 0 and (s < 0 or ev_time[e, s] > now[e]):
                break  # blocked on decisions
            if s < 0 or ev_time[e, s] >= horizon:
                done[e] = True
                for b in range(n_bus):
                    k = bus_ndec[e, b]
                    if k > 0:
                        dec_rew[e, b, k - 1] = bus_buffer[e, b]
                        dec_dur[e, b, k - 1] = horizon - bus_anchor[e, b]
                break
            t = ev_time[e, s]
            kind = ev_kind[e, s]
            arg = ev_arg[e, s]
            ev_kind[e, s] = -1
            now[e] = t
            if kind == INIT or kind == TRAVEL:
                b = arg
                if kind == TRAVEL:
                    bus_stop[e, b] = (bus_stop[e, b] + 1) % n_stop
                k = bus_stop[e, b]
                queue[e, k, (q_head[e, k] + q_len[e, k]) % n_bus] = b
                q_len[e, k] += 1
                kind = RELEASE  # a new request triggers the stop's queue like a release does
                arg = k
            if kind == RELEASE:
                k = arg
                if stop_busy[e, k] == 0 and q_len[e, k] > 0:
                    b = queue[e, k, q_head[e, k]]
                    q_head[e, k] = (q_head[e, k] + 1) % n_bus
                    q_len[e, k] -= 1
                    stop_busy[e, k] = 1
                    _push(ev_time, ev_prio, ev_id, ev_kind, ev_arg, next_id, e, t, NORMAL, GRANT, b)
            elif kind == GRANT:
                b = arg
                k = bus_stop[e, b]
                h = (t - stop_last_dep[e, k]) / 60.0
                d = h - headway
                r = -rate[k] * (d * d)  # as the reference: the correctly rounded square
                ep_return[e] += r
                for j in range(n_bus):
                    bus_buffer[e, j] += np.exp(-gamma * (t - bus_anchor[e, j])) * r
                a = n_arr[e]
                arr_time[e, a] = t
                arr_bus[e, a] = b
                arr_stop[e, a] = k
                arr_h[e, a] = h
                arr_load[e, a] = bus_load[e, b]
                n_arr[e] += 1
                bus_arr[e, b] = a
                d = bus_ndec[e, b]
                if d > 0:
                    dec_rew[e, b, d - 1] = bus_buffer[e, b]
                    dec_dur[e, b, d - 1] = t - bus_anchor[e, b]
                    bus_buffer[e, b] = 0.0
                dec_obs[e, b, d, 0] = k
                dec_obs[e, b, d, 1] = h
                dec_obs[e, b, d, 2] = bus_load[e, b]
                dec_obs[e, b, d, 3] = t - bus_anchor[e, b]
                bus_anchor[e, b] = t
                bus_ndec[e, b] = d + 1
                pending[e, n_pending[e]] = b
                n_pending[e] += 1
            elif kind == DECISION:
                b = arg
                k = bus_stop[e, b]
                a = bus_arr[e, b]
                load = bus_load[e, b]
                u = np.int64(np.floor(alight[k] * load + 0.5))
                bd = min(np.int64(np.floor(rate[k] * arr_h[e, a] + 0.5)), l_max - load + u)
                bus_load[e, b] = load - u + bd
                arr_u[e, a] = u
                arr_b[e, a] = bd
                hold = dec_act[e, b, bus_ndec[e, b] - 1]
                _push(ev_time, ev_prio, ev_id, ev_kind, ev_arg, next_id, e,
                      t + (max(t_a * u, t_b * bd) + hold * t_hold), NORMAL, DWELL, b)
            else:  # DWELL: depart, free the stop, travel on
                b = arg
                k = bus_stop[e, b]
                stop_last_dep[e, k] = t
                stop_busy[e, k] = 0
                _push(ev_time, ev_prio, ev_id, ev_kind, ev_arg, next_id, e, t, NORMAL, RELEASE, k)
                _push(ev_time, ev_prio, ev_id, ev_kind, ev_arg, next_id, e, t + rt, NORMAL, TRAVEL, b)
    return True


class BusBatch:
    """A batch of episodes advanced round by round (see the module docstring)."""

    def __init__(self, cfg: BusConfig, n_episodes: int):
        require(n_episodes >= 1, "n_episodes", "an integer >= 1", n_episodes)
        self.cfg = cfg
        e, n, k = n_episodes, cfg.n_buses, cfg.n_stops
        m = cfg.max_arrivals_per_bus
        cap = 2 * n  # scheduled at once: one event of each bus, plus the RELEASE of the stop it left
        self._cfg_args = (cfg.n_actions, np.asarray(cfg.alight_fraction, float),
                          np.asarray(cfg.arrival_rate, float), cfg.l_max, cfg.travel_time,
                          cfg.t_alight, cfg.t_board, cfg.headway, cfg.t_hold, cfg.gamma, cfg.horizon)
        self.now = np.zeros(e)
        self.done = np.zeros(e, bool)
        self.ep_return = np.zeros(e)
        self.next_id = np.zeros(e, np.int64)
        self.ev_time = np.zeros((e, cap))
        self.ev_prio = np.zeros((e, cap), np.int64)
        self.ev_id = np.zeros((e, cap), np.int64)
        self.ev_kind = np.full((e, cap), -1, np.int64)
        self.ev_arg = np.zeros((e, cap), np.int64)
        self.bus_stop = np.zeros((e, n), np.int64)
        self.bus_load = np.zeros((e, n), np.int64)
        self.bus_anchor = np.zeros((e, n))
        self.bus_buffer = np.zeros((e, n))
        self.bus_ndec = np.zeros((e, n), np.int64)
        self.bus_arr = np.zeros((e, n), np.int64)
        self.stop_busy = np.zeros((e, k), np.int64)
        self.stop_last_dep = np.zeros((e, k))
        self.queue = np.zeros((e, k, n), np.int64)
        self.q_head = np.zeros((e, k), np.int64)
        self.q_len = np.zeros((e, k), np.int64)
        self.pending = np.zeros((e, n), np.int64)
        self.n_pending = np.zeros(e, np.int64)
        self.dec_obs = np.zeros((e, n, m, OBS_DIM))
        self.dec_act = np.zeros((e, n, m), np.int64)
        self.dec_rew = np.zeros((e, n, m))
        self.dec_dur = np.zeros((e, n, m))
        self.arr_time = np.zeros((e, n * m))
        self.arr_bus = np.zeros((e, n * m), np.int64)
        self.arr_stop = np.zeros((e, n * m), np.int64)
        self.arr_h = np.zeros((e, n * m))
        self.arr_load = np.zeros((e, n * m), np.int64)
        self.arr_u = np.zeros((e, n * m), np.int64)
        self.arr_b = np.zeros((e, n * m), np.int64)
        self.n_arr = np.zeros(e, np.int64)
        # SimPy starts one process per bus with an URGENT initialisation event, in bus order.
        self.ev_kind[:, :n] = INIT
        self.ev_arg[:, :n] = np.arange(n)
        self.ev_prio[:, :n] = URGENT
        self.ev_id[:, :n] = np.arange(n)
        self.next_id[:] = n

    def advance(self, actions: np.ndarray) -> DecisionBatch:
        """Answer the pending decisions (one action per row of the last batch), run until blocked,
        and return the new pending decisions (empty once every episode has ended)."""
        actions = np.asarray(actions)
        require(len(actions) == int(self.n_pending.sum()), "actions",
                "one action per pending decision", len(actions))
        require(len(actions) == 0 or np.issubdtype(actions.dtype, np.integer), "actions",
                "integers", actions.dtype)
        offsets = np.concatenate([[0], np.cumsum(self.n_pending)[:-1]]).astype(np.int64)
        ok = _advance(actions.astype(np.int64), offsets, *self._cfg_args,
                      self.now, self.done, self.ep_return, self.next_id, self.ev_time,
                      self.ev_prio, self.ev_id, self.ev_kind, self.ev_arg, self.bus_stop,
                      self.bus_load, self.bus_anchor, self.bus_buffer, self.bus_ndec, self.bus_arr,
                      self.stop_busy, self.stop_last_dep, self.queue, self.q_head, self.q_len,
                      self.pending, self.n_pending, self.dec_obs, self.dec_act, self.dec_rew,
                      self.dec_dur, self.arr_time, self.arr_bus, self.arr_stop, self.arr_h,
                      self.arr_load, self.arr_u, self.arr_b, self.n_arr)
        require(ok, "action", f"an integer in 0..{self.cfg.n_actions - 1} (a hold of a * T_hold)",
                actions.tolist())
        return self.decisions()

    def decisions(self) -> DecisionBatch:
        ep, slot = np.nonzero(np.arange(self.cfg.n_buses)[None, :] < self.n_pending[:, None])
        agent = self.pending[ep, slot]
        index = self.bus_ndec[ep, agent] - 1
        return DecisionBatch(obs=self.dec_obs[ep, agent, index], episode=ep.astype(np.int64),
                             agent=agent, index=index)

    def arrivals(self) -> dict[str, np.ndarray]:
        """Every arrival of every episode, in processing order: episode, time (s), bus, stop
        (0-based), h (min), load at arrival, alighting U and boarding B."""
        mask = np.arange(self.arr_time.shape[1])[None, :] < self.n_arr[:, None]
        ep = np.nonzero(mask)[0]
        return dict(episode=ep, time=self.arr_time[mask], bus=self.arr_bus[mask],
                    stop=self.arr_stop[mask], h=self.arr_h[mask], load=self.arr_load[mask],
                    alight=self.arr_u[mask], board=self.arr_b[mask])

    def to_rollout(self) -> Rollout:
        require(bool(self.done.all()), "rollout", "taken after every episode has ended")
        e, n = self.bus_ndec.shape
        mask = np.arange(self.dec_act.shape[2])[None, None, :] < self.bus_ndec[:, :, None]
        lengths = self.bus_ndec.reshape(-1)
        return Rollout(
            obs=self.dec_obs[mask], actions=self.dec_act[mask], rewards=self.dec_rew[mask],
            durations=self.dec_dur[mask],
            path_start=np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
            path_episode=np.repeat(np.arange(e), n), path_agent=np.tile(np.arange(n), e),
            episode_return=self.ep_return.copy(), info={"arrivals": self.arrivals()})


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
