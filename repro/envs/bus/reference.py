"""The SimPy reference model of the bus corridor: the executable statement of docs/semantics.md
section 4 (the authors' released simulator, with each of its departures B1-B5 from the prose a
switch).

Each stop is a capacity-one ``simpy.Resource`` (its FIFO request queue is the queue of buses), and
each bus is a SimPy process::

    request Stop 1; on getting it: observe; then for ever: wait for the decision;
    serve (alight, board, dwell, hold, release the stop, travel, request the next stop; on getting
    it: headway, reward to every agent); observe.

Under B5 the service is a process of its own that starts DECISION_LATENCY after the decision and
that the bus waits for (as the released code does, so the observation comes two same-instant steps
after the arrival); without B5 it runs inline and the observation is the arrival's own step.

Decisions are batched like the fast engine's (``engine.py`` states the round and reward
conventions; this model shares only the parameters, ``params.py``, with it): a bus yields an
untriggered ``decision`` event; an episode runs until some bus waits and the next event lies
later; the driver then succeeds the waiting events with the policy's actions. The model favours
plainness over speed; ``engine.py`` must agree with it exactly.
"""

from __future__ import annotations

import math
from typing import Iterator

import numpy as np
import simpy

from repro.core.errors import require
from repro.core.paths import path_layout
from repro.core.rollout import DecisionBatch, Rollout, RunsToEnd, check_actions
from repro.envs.bus.params import DECISION_LATENCY, OBS_DIM, BusConfig


class _Episode:
    def __init__(self, cfg: BusConfig):
        self.cfg = cfg
        n, k = cfg.n_buses, cfg.n_stops
        self.env = simpy.Environment()
        self.stops = [simpy.Resource(self.env, capacity=1) for _ in range(k)]
        self.last_departure = [0.0] * k  # of any bus (headway without B2)
        self.departed = [[-1.0] * k for _ in range(n)]  # per bus; -1: not yet (B2)
        self.request: list[simpy.Event | None] = [None] * n  # the stop request each bus holds
        self.stop = [0] * n
        self.load = [0] * n
        self.visits = [0] * n  # stop visits so far, the start at Stop 1 being the first
        self.h = [0.0] * n  # headway (s) of the bus's latest visit
        self.anchor = [0.0] * n  # discount anchor: start of the running macro-action
        self.started = [True] * n  # the latest decision's action has started
        self.t_obs = [0.0] * n  # time of the latest observation
        self.buffer = [0.0] * n
        self.obs: list[list[list[float]]] = [[] for _ in range(n)]
        self.actions: list[list[int]] = [[] for _ in range(n)]
        self.rewards: list[list[float]] = [[] for _ in range(n)]
        self.durations: list[list[float]] = [[] for _ in range(n)]
        self.arrivals: list[list[float]] = []  # time, bus, stop, h, load, U, B
        self.episode_return = 0.0
        self.pending: list[tuple[int, simpy.Event]] = []
        self.done = False
        for b in range(n):
            self.env.process(self._bus(b))

    def _round(self, x: float) -> int:
        return round(x) if self.cfg.b4_round_half_even else math.floor(x + 0.5)

    def _headway(self, b: int, t: float) -> float:
        """h (s) of bus b getting its stop at t; -1 for unknown under B2."""
        k = self.stop[b]
        if not self.cfg.b2_headway:
            return t - self.last_departure[k]
        ahead = self.departed[(b - 1) % self.cfg.n_buses][k]
        return -1.0 if self.visits[b] == 1 or ahead < 0 else t - ahead

    def _reward(self, k: int, h: float, visit: int) -> float:
        cfg = self.cfg
        # d * d, not d ** 2: CPython's ** calls libm pow, which can be 1 ulp off the
        # correctly rounded square that compiled code (numba) computes
        if not cfg.b1_reward:
            d = h / 60.0 - cfg.headway
            return -cfg.arrival_rate[k] * (d * d)
        if h <= 0.0 or visit <= 2:
            return 0.0
        d = h - 60.0 * cfg.headway
        return -(cfg.arrival_rate[k] / 60.0) * (d * d)

    def _arrive(self, b: int) -> None:
        """Bus b got its stop: its headway, and the arrival's reward to every agent."""
        t = self.env.now
        self.visits[b] += 1
        h = self.h[b] = self._headway(b, t)
        r = self._reward(self.stop[b], h, self.visits[b])
        self.episode_return += r
        for j in range(self.cfg.n_buses):
            self.buffer[j] += math.exp(-self.cfg.gamma * (t - self.anchor[j])) * r

    def _close_macro_action(self, b: int, t: float) -> None:
        if self.actions[b]:
            self.rewards[b].append(self.buffer[b])
            # an action not started by the horizon (B5) lasts 0 s, as the released code records
            self.durations[b].append(t - self.anchor[b] if self.started[b] else 0.0)
            self.buffer[b] = 0.0

    def _observe(self, b: int) -> None:
        t = self.env.now
        self._close_macro_action(b, t)
        h = self.h[b]
        h_obs = h if self.cfg.b2_headway else h / 60.0
        self.obs[b].append([float(self.stop[b]), h_obs, float(self.load[b]), t - self.anchor[b]])
        self.t_obs[b] = t
        if not self.cfg.b5_timing:
            self.anchor[b] = t
        self.started[b] = False

    def _serve(self, b: int, action: int) -> Iterator[simpy.Event]:
        """Alight, board, dwell, hold, leave, travel, and get the next stop."""
        cfg, env = self.cfg, self.env
        t, k, load, visit = env.now, self.stop[b], self.load[b], self.visits[b]
        if cfg.b5_timing:
            self.anchor[b] = t
        self.started[b] = True
        alight = self._round(cfg.alight_fraction[k] * load)
        if cfg.b3_boarding:
            hb = self.h[b] if visit > 2 else t
            board = self._round(cfg.arrival_rate[k] / 60.0 * hb)
        else:
            board = self._round(cfg.arrival_rate[k] * (self.h[b] / 60.0))
        board = min(board, cfg.l_max - (load - alight))
        h_min = math.nan if cfg.b2_headway and self.h[b] == -1.0 else self.h[b] / 60.0
        self.arrivals.append([self.t_obs[b], b, k, h_min, load, alight, board])
        self.load[b] = load - alight + board
        dwell, hold = max(cfg.t_alight * alight, cfg.t_board * board), action * cfg.t_hold
        if cfg.b5_timing:
            yield env.timeout(dwell)
            yield env.timeout(hold)
        else:
            yield env.timeout(dwell + hold)
        self.stops[k].release(self.request[b])
        self.departed[b][k] = self.last_departure[k] = env.now
        yield env.timeout(cfg.travel_time)
        self.stop[b] = (k + 1) % cfg.n_stops
        self.request[b] = self.stops[self.stop[b]].request()
        yield self.request[b]
        self._arrive(b)

    def _bus(self, b: int) -> Iterator[simpy.Event]:
        env = self.env
        self.request[b] = self.stops[0].request()
        yield self.request[b]
        self._arrive(b)
        self._observe(b)  # its start at Stop 1: the bus's own process gets the stop, under B5 too
        while True:
            decision = env.event()
            self.pending.append((b, decision))
            action = yield decision
            self.actions[b].append(action)
            if self.cfg.b5_timing:
                yield env.timeout(DECISION_LATENCY)
                service = env.process(self._serve(b, action))
                # the released bus waits for its service or the episode's end: the condition is
                # one more same-instant step before it observes
                yield env.any_of([service])
            else:
                yield from self._serve(b, action)
            self._observe(b)

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
        actions = check_actions(actions, len(waiting), self.cfg.n_actions)
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
        path_start, path_episode, path_agent = path_layout(
            np.array([len(ep.actions[b]) for ep, b in paths]).reshape(len(eps), n))
        return Rollout(
            obs=np.array([o for ep, b in paths for o in ep.obs[b]], float).reshape(-1, OBS_DIM),
            actions=np.array([a for ep, b in paths for a in ep.actions[b]], np.int64),
            rewards=np.array([r for ep, b in paths for r in ep.rewards[b]], float),
            durations=np.array([d for ep, b in paths for d in ep.durations[b]], float),
            path_start=path_start, path_episode=path_episode, path_agent=path_agent,
            episode_return=np.array([ep.episode_return for ep in eps]),
            info={"arrivals": self.arrivals()})


class ReferenceBusEnv(RunsToEnd):
    """The SimPy reference as a :class:`repro.core.rollout.BatchEnv` (slow; for checking)."""

    name = "bus-reference"
    obs_dim = OBS_DIM

    def __init__(self, cfg: BusConfig | None = None):
        self.cfg = cfg or BusConfig()
        self.n_actions = self.cfg.n_actions
        self.n_agents = self.cfg.n_buses
        self.gamma = self.cfg.gamma

    def start(self, n_episodes: int) -> ReferenceBatch:
        return ReferenceBatch(self.cfg, n_episodes)
