"""PettingZoo views of one bus episode, driven by the fast engine: a ``ParallelEnv`` (the buses
waiting at one instant act together) and an AEC env (they act one by one, in arrival order).

Both follow the convention of :mod:`repro.core.parallel_env`, which the wildfire's views share:

- a bus's reward is its macro-action's: the arrival rewards -nu_k (h - H)^2 accrued from its
  decision to its next one (each arrival rewards every bus), each discounted by
  exp(-gamma (t - T_k)) to the macro-action's start T_k, as M-GAE consumes them (the rewards of
  arrivals before a bus's first decision go to its first macro-action, discounted to t = 0);
- ``infos[bus]`` holds that macro-action's ``duration`` (s) and ``time``, the clock at its end (the
  bus's new decision, or the horizon): 0 and 0 at a bus's first decision;
- the episode ends at the horizon: every bus is terminated (the bus has no decision limit, so
  nothing is truncated);
- observations [stop, headway h (s), load, time since the bus's last decision (s)] are float32,
  within :func:`observation_box`.

In the ParallelEnv a bus joins ``agents`` at its first decision (its first arrival at Stop 1), and
a step's dicts hold the buses deciding now and, at the horizon, every bus (see
:mod:`repro.core.parallel_env`). In the AEC env the selected bus's ``last()`` reward is its
macro-action's that ended with this decision (and, at the horizon, the one the horizon cut).

``parallel_env()`` is the ParallelEnv, ``env()`` the AEC environment in PettingZoo's usual
wrappers, ``raw_env()`` the bare one (all take ``cfg`` and ``render_mode``: "rgb_array", a picture
as an array, or "human", in a window; see :mod:`repro.envs.bus.render`). The environment is
deterministic: ``seed`` is accepted and unused.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from pettingzoo import AECEnv
from pettingzoo.utils import wrappers

from repro.core.canvas import RENDER_MODES, Canvas, Renders
from repro.core.errors import require
from repro.core.parallel_env import EventParallelEnv
from repro.envs.bus.engine import BusBatch
from repro.envs.bus.params import BusConfig
from repro.envs.bus.render import draw, frame_of_state
from repro.envs.bus.vector import BusVectorEnv


def observation_box(cfg: BusConfig) -> spaces.Box:
    """Bounds of an observation: the stop (0..K-1), the headway (s; within the horizon, and -1
    where quirk B2 reports an unknown one), the load (0..l_max), the time since the bus's last
    decision (within the horizon)."""
    high = np.array([cfg.n_stops - 1, cfg.horizon, cfg.l_max, cfg.horizon])
    low = np.array([0.0, -1.0 if cfg.b2_headway else 0.0, 0.0, 0.0])
    return spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)


class BusAECEnv(Renders, AECEnv):
    metadata = {"name": "bus_v0", "render_modes": list(RENDER_MODES), "is_parallelizable": False,
                "render_fps": 4}

    def __init__(self, cfg: BusConfig | None = None, render_mode: str | None = None):
        super().__init__()
        require(render_mode is None or render_mode in RENDER_MODES, "render_mode",
                f"None or one of {', '.join(RENDER_MODES)}", render_mode)
        self.cfg = cfg or BusConfig()
        self.render_mode = render_mode
        self._canvas: Canvas | None = None
        self.possible_agents = [f"bus_{i}" for i in range(self.cfg.n_buses)]
        box = observation_box(self.cfg)
        self.observation_spaces = {a: box for a in self.possible_agents}
        self.action_spaces = {a: spaces.Discrete(self.cfg.n_actions) for a in self.possible_agents}

    def observation_space(self, agent: str) -> spaces.Box:
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Discrete:
        return self.action_spaces[agent]

    def reset(self, seed: int | None = None, options: dict | None = None) -> None:
        """The environment is deterministic; ``seed`` is accepted and unused."""
        self.agents = list(self.possible_agents)
        self.rewards = {a: 0.0 for a in self.agents}
        self._cumulative_rewards = {a: 0.0 for a in self.agents}
        self.terminations = {a: False for a in self.agents}
        self.truncations = {a: False for a in self.agents}
        self.infos = {a: {"duration": 0.0, "time": 0.0} for a in self.agents}
        box = observation_box(self.cfg)
        self._obs = {a: np.zeros(box.shape, box.dtype) for a in self.agents}
        self._clock = np.zeros(len(self.agents))  # each bus's T_k: its macro-actions' durations
        self._batch = BusBatch(self.cfg, 1)
        self._actions: list[int] = []
        self._step_engine()

    def _step_engine(self) -> None:
        """Give the round's actions, run to the next decisions; reward the macro-actions that
        ended (those of the buses deciding again, or every bus's at the horizon)."""
        b = self._batch
        decisions = b.advance(np.array(self._actions, np.int64))
        self._actions = []
        if b.done[0]:
            n_dec = b.n_decisions[0]
            agent = np.flatnonzero(n_dec > 0)
            index = n_dec[agent] - 1
        else:
            again = decisions.index > 0
            agent, index = decisions.agent[again], decisions.index[again] - 1
        reward, duration = b.macro_actions(np.zeros_like(agent), agent, index)
        self.rewards = {a: 0.0 for a in self.agents}
        for i, r, dt in zip(agent, reward, duration):
            self._clock[i] += dt
            a = self.possible_agents[i]
            self.rewards[a] = float(r)
            self.infos[a] = {"duration": float(dt), "time": float(self._clock[i])}
        self._queue = [self.possible_agents[i] for i in decisions.agent]
        for name, o in zip(self._queue, decisions.obs):
            self._obs[name] = o.astype(np.float32)
        self._accumulate_rewards()
        if not self._queue:
            self.terminations = {a: True for a in self.agents}
            self.agent_selection = self.agents[0]
        else:
            self.agent_selection = self._queue[0]

    def observe(self, agent: str) -> np.ndarray:
        return self._obs[agent].copy()

    def step(self, action: int | None) -> None:
        agent = self.agent_selection
        if self.terminations[agent] or self.truncations[agent]:
            self._was_dead_step(action)
            return
        self._cumulative_rewards[agent] = 0.0
        self._actions.append(int(action))
        self._queue.pop(0)
        if self._queue:
            self.rewards = {a: 0.0 for a in self.agents}
            self.agent_selection = self._queue[0]
        else:
            self._step_engine()

    def _draw(self, figure) -> None:
        """The corridor now: the buses where they are, with their loads."""
        draw(figure, frame_of_state(self.cfg, self._batch.state(0)), self.cfg)

    def close(self) -> None:
        if self._canvas is not None:
            self._canvas.close()
            self._canvas = None


class BusParallelEnv(EventParallelEnv):
    """The buses deciding at one instant act together (see the module docstring)."""

    metadata = {"name": "bus_v0", "render_modes": list(RENDER_MODES), "render_fps": 4}

    def __init__(self, cfg: BusConfig | None = None, render_mode: str | None = None):
        require(render_mode is None or render_mode in RENDER_MODES, "render_mode",
                f"None or one of {', '.join(RENDER_MODES)}", render_mode)
        self.cfg = cfg or BusConfig()
        super().__init__(lambda seed: BusVectorEnv(self.cfg, 1), "bus", observation_box(self.cfg),
                         self.cfg.n_buses, self.cfg.n_actions, render_mode)

    def _draw(self, figure) -> None:
        """The corridor now: the buses where they are, with their loads."""
        draw(figure, frame_of_state(self.cfg, self._vec.batch.state(0)), self.cfg)


def parallel_env(cfg: BusConfig | None = None,
                 render_mode: str | None = None) -> BusParallelEnv:
    """The ParallelEnv."""
    return BusParallelEnv(cfg, render_mode)


def raw_env(cfg: BusConfig | None = None, render_mode: str | None = None) -> BusAECEnv:
    """The bare AEC environment."""
    return BusAECEnv(cfg, render_mode)


def env(cfg: BusConfig | None = None, render_mode: str | None = None) -> AECEnv:
    """The AEC environment in PettingZoo's usual wrappers (actions checked, calls in order)."""
    return wrappers.OrderEnforcingWrapper(wrappers.AssertOutOfBoundsWrapper(
        raw_env(cfg, render_mode)))
