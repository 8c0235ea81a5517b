"""A PettingZoo AEC view of the SimPy wildfire model: the UAV whose decision comes next acts.

After each ``step`` the model runs until the next UAV observes; that UAV is selected, its reward
is its just-finished macro-action's reward (discounted to the action's start, SPEC 3) and its info
holds the macro-action's ``duration`` and the simulation ``time``. When the episode ends every
UAV's running macro-action is cut and rewarded; the episode is terminated if all fires are out,
truncated at T_max.

``env()`` is the environment in PettingZoo's usual wrappers, ``raw_env()`` the bare one (both take
``cfg`` and ``render_mode``: "rgb_array", a picture as an array, or "human", in a window; see
:mod:`repro.envs.wildfire.render`).
"""

from __future__ import annotations

import gymnasium
import numpy as np
from pettingzoo import AECEnv
from pettingzoo.utils import wrappers

from repro.core.canvas import RENDER_MODES, Canvas
from repro.core.errors import require
from repro.envs.wildfire.params import WildfireConfig, draw_episodes, fire_positions
from repro.envs.wildfire.reference import WildfireModel
from repro.envs.wildfire.render import draw, frame_of_model


class WildfireAECEnv(AECEnv):
    metadata = {"name": "wildfire_v0", "render_modes": list(RENDER_MODES),
                "is_parallelizable": False, "render_fps": 4}

    def __init__(self, cfg: WildfireConfig | None = None, render_mode: str | None = None):
        super().__init__()
        cfg = cfg or WildfireConfig()
        cfg.validate()
        require(render_mode is None or render_mode in RENDER_MODES, "render_mode",
                f"None or one of {', '.join(RENDER_MODES)}", render_mode)
        self.cfg = cfg
        self.render_mode = render_mode
        self._canvas: Canvas | None = None
        self.possible_agents = [f"uav_{i}" for i in range(cfg.n_agents)]
        self._obs_space = observation_box(cfg)
        self._act_space = gymnasium.spaces.Discrete(cfg.n_actions)
        self._seed_seq = np.random.SeedSequence()
        self.model: WildfireModel | None = None

    def observation_space(self, agent: str) -> gymnasium.spaces.Box:
        return self._obs_space

    def action_space(self, agent: str) -> gymnasium.spaces.Discrete:
        return self._act_space

    def reset(self, seed: int | None = None, options: dict | None = None) -> None:
        if seed is not None:
            self._seed_seq = np.random.SeedSequence(seed)
        draws = draw_episodes(self.cfg, 1, self._seed_seq.spawn(1)[0])
        self.model = WildfireModel(self.cfg, draws.starts[0], draws.holds[0])
        self.agents = list(self.possible_agents)
        self.rewards = {a: 0.0 for a in self.agents}
        self._cumulative_rewards = {a: 0.0 for a in self.agents}
        self.terminations = {a: False for a in self.agents}
        self.truncations = {a: False for a in self.agents}
        self.infos = {a: {"duration": 0.0, "time": 0.0} for a in self.agents}
        self._run()

    def render(self) -> np.ndarray | None:
        """The state now: fires with their health and status, UAVs with their targets."""
        if self.render_mode is None:
            gymnasium.logger.warn("render() without a render_mode: give one to the constructor")
            return None
        if self._canvas is None:
            self._canvas = Canvas(self.render_mode)
        draw(self._canvas.figure, frame_of_model(self.model), self.cfg)
        return self._canvas.show()

    def close(self) -> None:
        if self._canvas is not None:
            self._canvas.close()
            self._canvas = None

    def observe(self, agent: str) -> np.ndarray:
        i = self.possible_agents.index(agent)
        return np.array(self.model.rec[self.model.current[i]]["obs"], dtype=np.float64)

    def step(self, action: int | None) -> None:
        agent = self.agent_selection
        if self.terminations[agent] or self.truncations[agent]:
            self._was_dead_step(action)
            return
        self._cumulative_rewards[agent] = 0.0
        self.model.act(self.possible_agents.index(agent), int(action))
        self._run()

    def _run(self) -> None:
        """Advance to the next decision (or the end) and publish the rewards that it completes."""
        m = self.model
        m.advance()
        self.rewards = {a: 0.0 for a in self.agents}
        if m.done:
            all_out = not any(m.alive)
            for i, a in enumerate(self.possible_agents):
                rec = m.rec[m.current[i]]
                self.rewards[a] = rec["reward"]
                self.infos[a] = {"duration": rec["duration"], "time": m.t_end}
                self.terminations[a] = all_out
                self.truncations[a] = not all_out
            self.agent_selection = self.agents[0]
        else:
            i = m.pending[0]
            a = self.possible_agents[i]
            prev = m.rec[m.current[i]]["prev"]
            if prev >= 0:
                self.rewards[a] = m.rec[prev]["reward"]
                self.infos[a] = {"duration": m.rec[prev]["duration"], "time": m.env.now}
            self.agent_selection = a
        self._accumulate_rewards()


def observation_box(cfg: WildfireConfig) -> gymnasium.spaces.Box:
    """Bounds of an observation: own x, y (UAVs start uniformly on [-1, 1]^2 and fly straight
    between starts and fires, so they stay in the square that holds both); per observed fire its
    distance (at most the square's diagonal), level (always 1; bounds 0..1, as a Box with equal
    bounds draws PettingZoo's warning), interest party size (0..N), status (0 or 1) and remaining
    health (0..T_health; with quirk Q3 it drains on, at most N UAVs until T_max); the sojourn time
    (0..T_max)."""
    side = max(1.0, float(np.abs(fire_positions(cfg)).max()))
    lowest_health = cfg.t_health - cfg.n_agents * cfg.t_max if cfg.quirk_q3_unclamped_health else 0
    per_fire_low = [0, 0, 0, 0, lowest_health]
    per_fire_high = [2 * np.sqrt(2) * side, 1, cfg.n_agents, 1, cfg.t_health]
    low = [-side, -side, *per_fire_low * cfg.n_observed, 0]
    high = [side, side, *per_fire_high * cfg.n_observed, cfg.t_max]
    return gymnasium.spaces.Box(np.array(low, float), np.array(high, float), dtype=np.float64)


def raw_env(cfg: WildfireConfig | None = None, render_mode: str | None = None) -> WildfireAECEnv:
    """The bare AEC environment."""
    return WildfireAECEnv(cfg, render_mode)


def env(cfg: WildfireConfig | None = None, render_mode: str | None = None) -> AECEnv:
    """The AEC environment in PettingZoo's usual wrappers (actions checked, calls in order)."""
    return wrappers.OrderEnforcingWrapper(wrappers.AssertOutOfBoundsWrapper(
        raw_env(cfg, render_mode)))
