"""A PettingZoo AEC view of one bus episode, driven by the fast engine.

Agents ``bus_0`` .. ``bus_5`` act in the engine's round order (the buses waiting at one instant, in
arrival order). After each round of actions the engine runs until the next decisions; every agent's
reward for that stretch is the undiscounted sum of the arrival rewards -nu_k (h - H)^2 it accrued
(each arrival rewards every agent); the rewards of arrivals before the first action (at reset) are
paid with those of the first round, since AEC rewards follow steps. At the horizon all agents are
truncated.

``env()`` is the environment in PettingZoo's usual wrappers, ``raw_env()`` the bare one (both take
``cfg`` and ``render_mode``: "rgb_array", a picture as an array, or "human", in a window; see
:mod:`repro.envs.bus.render`).
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from pettingzoo import AECEnv
from pettingzoo.utils import wrappers

from repro.core.canvas import RENDER_MODES, Canvas, Renders
from repro.core.errors import require
from repro.envs.bus.engine import OBS_DIM, BusBatch
from repro.envs.bus.params import BusConfig
from repro.envs.bus.render import draw, frame_of_state


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
        # a headway and the time since the bus's last action are within the episode
        high = np.array([self.cfg.n_stops - 1, self.cfg.horizon, self.cfg.l_max, self.cfg.horizon])
        # B2 reports an unknown headway as -1
        low = np.array([0.0, -1.0 if self.cfg.b2_headway else 0.0, 0.0, 0.0])
        self.observation_spaces = {a: spaces.Box(low, high, dtype=np.float64)
                                   for a in self.possible_agents}
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
        self.infos = {a: {} for a in self.agents}
        self._obs = {a: np.zeros(OBS_DIM) for a in self.agents}
        self._batch = BusBatch(self.cfg, 1)
        self._actions: list[int] = []
        self._carry = 0.0
        self._step_engine()
        self._carry = sum(self.rewards.values()) / len(self.agents)
        self.rewards = {a: 0.0 for a in self.agents}
        self._cumulative_rewards = {a: 0.0 for a in self.agents}

    def _step_engine(self) -> None:
        before = float(self._batch.ep_return[0])
        decisions = self._batch.advance(np.array(self._actions, np.int64))
        gained = float(self._batch.ep_return[0]) - before + self._carry
        self._actions, self._carry = [], 0.0
        self._queue = [self.possible_agents[b] for b in decisions.agent]
        for name, o in zip(self._queue, decisions.obs):
            self._obs[name] = o.copy()
        self.rewards = {a: gained for a in self.agents}
        self._accumulate_rewards()
        if not self._queue:
            self.truncations = {a: True for a in self.agents}
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


def raw_env(cfg: BusConfig | None = None, render_mode: str | None = None) -> BusAECEnv:
    """The bare AEC environment."""
    return BusAECEnv(cfg, render_mode)


def env(cfg: BusConfig | None = None, render_mode: str | None = None) -> AECEnv:
    """The AEC environment in PettingZoo's usual wrappers (actions checked, calls in order)."""
    return wrappers.OrderEnforcingWrapper(wrappers.AssertOutOfBoundsWrapper(
        raw_env(cfg, render_mode)))
