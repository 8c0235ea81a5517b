"""The SimPy reference model of the bus corridor: the executable statement of SPEC section 5.2.

Each stop is a capacity-one ``simpy.Resource`` (its FIFO request queue is the queue of buses), and
each bus is a SimPy process::

    request the stop; on getting it (arrival): headway, reward to every agent, observe,
    wait for the decision; alight, board; hold dwell + a * T_hold; record the departure;
    release the stop; travel rt; next stop.

Decisions are batched like the fast engine's (see ``engine.py`` for the round and reward
conventions): a bus yields an untriggered ``decision`` event; an episode runs until some bus waits
and the next event lies later; the driver then succeeds the waiting events with the policy's
actions. The model favours plainness over speed; ``engine.py`` must agree with it exactly.
"""

from __future__ import annotations

import math
from typing import Iterator

import numpy as np
import simpy

from repro.core.errors import require
from repro.core.rollout import DecisionBatch, Rollout
from repro.envs.bus.engine import OBS_DIM, BusEnv
from repro.envs.bus.params import BusConfig


class _Episode:
    def __init__(self, cfg: BusConfig):
        self.cfg = cfg
        self.env = simpy.Environment()
        self.stops = [simpy.Resource(self.env, capacity=1) for _ in range(cfg.n_stops)]
        self.last_departure = [0.0] * cfg.n_stops
        self.anchor = [0.0] * cfg.n_buses
        self.buffer = [0.0] * cfg.n_buses
        self.obs: list[list[list[float]]] = [[] for _ in range(cfg.n_buses)]
        self.actions: list[list[int]] = [[] for _ in range(cfg.n_buses)]
        self.rewards: list[list[float]] = [[] for _ in range(cfg.n_buses)]
        self.durations: list[list[float]] = [[] for _ in range(cfg.n_buses)]
        self.arrivals: list[list[float]] = []  # time, bus, stop, h, load, U, B
        self.episode_return = 0.0
        self.pending: list[tuple[int, simpy.Event]] = []
        self.done = False
        for b in range(cfg.n_buses):
            self.env.process(self._bus(b))

    def _close_macro_action(self, b: int, t: float) -> None:
        if self.actions[b]:
            self.rewards[b].append(self.buffer[b])
            self.durations[b].append(t - self.anchor[b])
            self.buffer[b] = 0.0

    def _bus(self, b: int) -> Iterator[simpy.Event]:
        cfg, env = self.cfg, self.env
        stop, load = 0, 0
        while True:
            with self.stops[stop].request() as granted:
                yield granted
                t = env.now
                h = (t - self.last_departure[stop]) / 60.0
                # d * d, not d ** 2: CPython's ** calls libm pow, which can be 1 ulp off the
                # correctly rounded square that compiled code (numba) computes
                d = h - cfg.headway
                r = -cfg.arrival_rate[stop] * (d * d)
                self.episode_return += r
                for j in range(cfg.n_buses):
                    self.buffer[j] += math.exp(-cfg.gamma * (t - self.anchor[j])) * r
                self._close_macro_action(b, t)
                self.obs[b].append([float(stop), h, float(load), t - self.anchor[b]])
                self.anchor[b] = t
                decision = env.event()
                self.pending.append((b, decision))
                action = yield decision
                self.actions[b].append(action)
                alight = math.floor(cfg.alight_fraction[stop] * load + 0.5)
                board = min(math.floor(cfg.arrival_rate[stop] * h + 0.5), cfg.l_max - load + alight)
                self.arrivals.append([t, b, stop, h, load, alight, board])
                load = load - alight + board
                yield env.timeout(max(cfg.t_alight * alight, cfg.t_board * board)
                                  + action * cfg.t_hold)
                self.last_departure[stop] = env.now
            yield env.timeout(cfg.travel_time)
            stop = (stop + 1) % cfg.n_stops

    def advance(self) -> None:
        """Process events until blocked on decisions or past the horizon."""
        env = self.env
        while True:
            t = env.peek()
            if self.pending and t > env.now:
                return
            if t >= self.cfg.horizon:
                self.done = True
                for b in range(self.cfg.n_buses):
                    self._close_macro_action(b, self.cfg.horizon)
                return
            env.step()


class ReferenceBatch:
    """The same round interface as :class:`repro.envs.bus.engine.BusBatch`."""

    def __init__(self, cfg: BusConfig, n_episodes: int):
        require(n_episodes >= 1, "n_episodes", "an integer >= 1", n_episodes)
        self.cfg = cfg
        self.episodes = [_Episode(cfg) for _ in range(n_episodes)]

    def advance(self, actions: np.ndarray) -> DecisionBatch:
        waiting = [(ep, b, ev) for ep in self.episodes for b, ev in ep.pending]
        require(len(actions) == len(waiting), "actions", "one action per pending decision",
                len(actions))
        require(all(0 <= int(a) < self.cfg.n_actions for a in actions), "action",
                f"an integer in 0..{self.cfg.n_actions - 1} (a hold of a * T_hold)",
                [int(a) for a in actions])
        for (_, _, ev), a in zip(waiting, actions):
            ev.succeed(int(a))
        rows = []
        for e, ep in enumerate(self.episodes):
            ep.pending = []
            if not ep.done:
                ep.advance()
                rows += [(e, b, len(ep.obs[b]) - 1, ep.obs[b][-1]) for b, _ in ep.pending]
        return DecisionBatch(
            obs=np.array([r[3] for r in rows], float).reshape(-1, OBS_DIM),
            episode=np.array([r[0] for r in rows], np.int64),
            agent=np.array([r[1] for r in rows], np.int64),
            index=np.array([r[2] for r in rows], np.int64))

    def arrivals(self) -> dict[str, np.ndarray]:
        rows = np.array([[e] + a for e, ep in enumerate(self.episodes) for a in ep.arrivals])
        cols = ("episode", "time", "bus", "stop", "h", "load", "alight", "board")
        return {c: rows[:, i] if c in ("time", "h") else rows[:, i].astype(np.int64)
                for i, c in enumerate(cols)}

    def to_rollout(self) -> Rollout:
        eps = self.episodes
        n = self.cfg.n_buses
        paths = [(ep, b) for ep in eps for b in range(n)]
        lengths = [len(ep.actions[b]) for ep, b in paths]
        return Rollout(
            obs=np.array([o for ep, b in paths for o in ep.obs[b]], float).reshape(-1, OBS_DIM),
            actions=np.array([a for ep, b in paths for a in ep.actions[b]], np.int64),
            rewards=np.array([r for ep, b in paths for r in ep.rewards[b]], float),
            durations=np.array([d for ep, b in paths for d in ep.durations[b]], float),
            path_start=np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
            path_episode=np.repeat(np.arange(len(eps)), n),
            path_agent=np.tile(np.arange(n), len(eps)),
            episode_return=np.array([ep.episode_return for ep in eps]),
            info={"arrivals": self.arrivals()})


class ReferenceBusEnv(BusEnv):
    """The SimPy reference as a :class:`repro.core.rollout.BatchEnv` (slow; for checking): the
    fast engine's environment with the SimPy batch in its place."""

    name = "bus-reference"
    batch_type = ReferenceBatch
