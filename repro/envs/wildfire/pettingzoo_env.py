"""PettingZoo views of a wildfire episode: an AEC env on the SimPy model or the fast engine (the
UAV whose decision comes next acts) and a ``ParallelEnv`` on the fast engine (the UAVs whose
decisions are pending at once act together: those that observed within one decision latency).

Both follow the convention of :mod:`repro.core.parallel_env`, which the bus's views share:

- a UAV's reward is its macro-action's: the rewards accrued from its decision to its next
  observation (or the episode's end), each discounted by exp(-gamma (t - T_k)) to the
  macro-action's start T_k (docs/semantics.md section 2.2), as M-GAE consumes them;
- ``infos[uav]`` holds that macro-action's ``duration`` (s) and ``time``, the clock at its end
  (the UAV's new decision, or the episode's end): 0 and 0 at a UAV's first decision;
- the episode is terminated when all fires are out or at T_max, and truncated when it is cut at
  the decision limit (``max_decisions``); either way every UAV's running macro-action is cut and
  rewarded;
- observations are float32, within :func:`observation_box`.

In the AEC env, after each ``step`` the model runs until the next UAV observes; that UAV is
selected, and its ``last()`` reward and info are those of its just-finished macro-action. In the
ParallelEnv a step's dicts hold the UAVs deciding now and, once the episode ends, every UAV (see
:mod:`repro.core.parallel_env`, also for a UAV with two decisions pending at once).

``parallel_env()`` is the ParallelEnv, ``env()`` the AEC environment in PettingZoo's usual
wrappers, ``raw_env()`` the bare one (all take ``cfg`` and ``render_mode``: "rgb_array", a picture
as an array, or "human", in a window, see :mod:`repro.envs.wildfire.render`; the AEC ones take
``engine``). With ``engine="fast"`` the AEC episode runs on the fast engine's rounds
(:class:`repro.envs.wildfire.engine.WildfireBatch`), whose decisions are handed out one by one,
with the same observations, rewards and durations as the SimPy model's (the default,
``"reference"``); once numba has compiled it (or loaded its cache: the first episode), it steps
about twice as fast (the AEC's own bookkeeping then dominates). ``observe`` of an agent not
selected may then show a decision of the round that it has not been handed yet.
"""

from __future__ import annotations

import gymnasium
import numpy as np
from pettingzoo import AECEnv
from pettingzoo.utils import wrappers

from repro.core.canvas import RENDER_MODES, Canvas, Renders
from repro.core.errors import require
from repro.core.parallel_env import EventParallelEnv
from repro.envs.wildfire.engine import WildfireBatch, WildfireEnv
from repro.envs.wildfire.params import (DIST, HEALTH, INTEREST, LEVEL, OWN_X, OWN_Y, SOJOURN,
                                        STATUS, EpisodeDraws, WildfireConfig, draw_episodes,
                                        fire_blocks, fire_positions)
from repro.envs.wildfire.reference import WildfireModel
from repro.envs.wildfire.render import Frame, draw, frame_of_model, frame_of_state
from repro.envs.wildfire.vector import WildfireVectorEnv

ENGINES = ("reference", "fast")
"""What runs the AEC environment's episode."""


class _ReferenceEpisode:
    """One episode of the SimPy model, one decision at a time."""

    def __init__(self, cfg: WildfireConfig, draws: EpisodeDraws):
        self.model = WildfireModel(cfg, draws.starts[0], draws.holds[0])

    def next_agent(self) -> int | None:
        """Run to the next decision: its UAV, or None once the episode is over."""
        m = self.model
        m.advance()
        return None if m.done else m.pending[0]

    def act(self, i: int, action: int) -> None:
        self.model.act(i, action)

    def observation(self, i: int) -> np.ndarray:
        return np.array(self.model.rec[self.model.uav[i].current]["obs"], dtype=np.float32)

    def previous(self, i: int) -> tuple[float, float] | None:
        """The reward and duration of the macro-action before UAV i's decision now, if any."""
        m = self.model
        prev = m.rec[m.uav[i].current]["prev"]
        return None if prev < 0 else (m.rec[prev]["reward"], m.rec[prev]["duration"])

    def last(self, i: int) -> tuple[float, float]:
        """The reward and duration of UAV i's last macro-action, once the episode is over."""
        rec = self.model.rec[self.model.uav[i].current]
        return rec["reward"], rec["duration"]

    def truncated(self) -> bool:
        """The episode was cut at the decision limit."""
        return self.model.truncated

    def frame(self) -> Frame:
        return frame_of_model(self.model)


class _FastEpisode:
    """One episode of the fast engine: each round's decisions handed out in order, the round's
    actions given together."""

    def __init__(self, cfg: WildfireConfig, draws: EpisodeDraws):
        self.env = WildfireEnv(cfg)
        self.batch = WildfireBatch(self.env, draws)
        self.answers: list[int] = []
        self.handed = np.full(cfg.n_agents, -1)  # each UAV's decision (log row) handed out last

    def next_agent(self) -> int | None:
        b = self.batch
        if b.n_pending and len(self.answers) == b.n_pending:
            b.act(np.array(self.answers, np.int64))
            self.answers = []
        if not b.n_pending:  # a live episode always waits on a decision
            return None
        row = b.first + len(self.answers)
        i = int(b.log[row]["agent"])
        self.previous_row, self.handed[i] = self.handed[i], row
        return i

    def act(self, i: int, action: int) -> None:
        self.answers.append(action)

    def observation(self, i: int) -> np.ndarray:
        return self.batch.log[self.batch.states[0]["running_row"][i]]["obs"].astype(np.float32)

    def previous(self, i: int) -> tuple[float, float] | None:
        row = self.batch.log[self.previous_row] if self.previous_row >= 0 else None
        return None if row is None else (float(row["rew"]), float(row["dur"]))

    def last(self, i: int) -> tuple[float, float]:
        row = self.batch.log[self.batch.states[0]["running_row"][i]]
        return float(row["rew"]), float(row["dur"])

    def truncated(self) -> bool:
        return bool(self.batch.states[0]["truncated"])

    def frame(self) -> Frame:
        return frame_of_state(self.env, self.batch.states[0])


class WildfireAECEnv(Renders, AECEnv):
    metadata = {"name": "wildfire_v0", "render_modes": list(RENDER_MODES),
                "is_parallelizable": False, "render_fps": 4}

    def __init__(self, cfg: WildfireConfig | None = None, render_mode: str | None = None,
                 engine: str = "reference"):
        super().__init__()
        cfg = cfg or WildfireConfig()
        cfg.validate()
        require(render_mode is None or render_mode in RENDER_MODES, "render_mode",
                f"None or one of {', '.join(RENDER_MODES)}", render_mode)
        require(engine in ENGINES, "engine", " or ".join(ENGINES), engine)
        self._episode_type = _ReferenceEpisode if engine == "reference" else _FastEpisode
        self.cfg = cfg
        self.render_mode = render_mode
        self._canvas: Canvas | None = None
        self.possible_agents = [f"uav_{i}" for i in range(cfg.n_agents)]
        self._obs_space = observation_box(cfg)
        self._act_space = gymnasium.spaces.Discrete(cfg.n_actions)
        self._seed_seq = np.random.SeedSequence()

    def observation_space(self, agent: str) -> gymnasium.spaces.Box:
        return self._obs_space

    def action_space(self, agent: str) -> gymnasium.spaces.Discrete:
        return self._act_space

    def reset(self, seed: int | None = None, options: dict | None = None) -> None:
        if seed is not None:
            self._seed_seq = np.random.SeedSequence(seed)
        draws = draw_episodes(self.cfg, 1, self._seed_seq.spawn(1)[0])
        self._episode = self._episode_type(self.cfg, draws)
        self.agents = list(self.possible_agents)
        self.rewards = {a: 0.0 for a in self.agents}
        self._cumulative_rewards = {a: 0.0 for a in self.agents}
        self.terminations = {a: False for a in self.agents}
        self.truncations = {a: False for a in self.agents}
        self.infos = {a: {"duration": 0.0, "time": 0.0} for a in self.agents}
        self._clock = np.zeros(len(self.agents))  # each UAV's T_k: its macro-actions' durations
        self._run()

    def _draw(self, figure) -> None:
        """The state now: fires with their health and status, UAVs with their targets."""
        draw(figure, self._episode.frame(), self.cfg)

    def close(self) -> None:
        if self._canvas is not None:
            self._canvas.close()
            self._canvas = None

    def observe(self, agent: str) -> np.ndarray:
        return self._episode.observation(self.possible_agents.index(agent))

    def step(self, action: int | None) -> None:
        agent = self.agent_selection
        if self.terminations[agent] or self.truncations[agent]:
            self._was_dead_step(action)
            return
        self._cumulative_rewards[agent] = 0.0
        self._episode.act(self.possible_agents.index(agent), int(action))
        self._run()

    def _run(self) -> None:
        """Advance to the next decision (or the end) and publish the rewards that it completes."""
        ep = self._episode
        i = ep.next_agent()
        self.rewards = {a: 0.0 for a in self.agents}
        if i is None:
            truncated = ep.truncated()
            for j, a in enumerate(self.possible_agents):
                self._reward(j, *ep.last(j))
                self.terminations[a] = not truncated
                self.truncations[a] = truncated
            self.agent_selection = self.agents[0]
        else:
            previous = ep.previous(i)
            if previous is not None:
                self._reward(i, *previous)
            self.agent_selection = self.possible_agents[i]
        self._accumulate_rewards()

    def _reward(self, i: int, reward: float, duration: float) -> None:
        """UAV i's macro-action ended: its reward, duration and end time."""
        a = self.possible_agents[i]
        self._clock[i] += duration
        self.rewards[a] = float(reward)
        self.infos[a] = {"duration": float(duration), "time": float(self._clock[i])}


def observation_box(cfg: WildfireConfig) -> gymnasium.spaces.Box:
    """Bounds of an observation: own x, y (UAVs start uniformly on [-1, 1]^2 and fly straight
    between starts and fires, so they stay in the square that holds both); per observed fire its
    distance (at most the square's diagonal), level (always 1; bounds 0..1, as a Box with equal
    bounds draws PettingZoo's warning), interest party size (0..N), status (0 or 1) and remaining
    health; the sojourn time (0..T_max). Float32, as the observations the PettingZoo views hand
    out.

    The health is 0..T_health without quirk Q3. With Q3 it is unclamped, and a fire that is out
    keeps draining at the rate of the party it had (at most N UAVs) until T_max; a fire drains
    at most N per second from t = 0, so T_health - N T_max bounds it, and the bound is tight: N
    UAVs that start at a fire and attack it at once reach it but for a decision latency (-791.7
    at the paper's three UAVs and T_max = 264.9 s; random holding reached -475 over 2,000
    episodes, the nearest-fire heuristic -253)."""
    side = max(1.0, float(np.abs(fire_positions(cfg)).max()))
    lowest_health = cfg.t_health - cfg.n_agents * cfg.t_max if cfg.quirk_q3_unclamped_health else 0
    low, high = np.zeros(cfg.obs_dim), np.zeros(cfg.obs_dim)
    low[[OWN_X, OWN_Y]], high[[OWN_X, OWN_Y]] = -side, side
    low_fires, high_fires = fire_blocks(low[None], cfg.n_observed), fire_blocks(high[None],
                                                                                cfg.n_observed)
    low_fires[..., HEALTH] = lowest_health
    for column, top in ((DIST, 2 * np.sqrt(2) * side), (LEVEL, 1), (INTEREST, cfg.n_agents),
                        (STATUS, 1), (HEALTH, cfg.t_health)):
        high_fires[..., column] = top
    high[SOJOURN] = cfg.t_max
    return gymnasium.spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)


class WildfireParallelEnv(EventParallelEnv):
    """The UAVs whose decisions are pending at once act together, on the fast engine (see the
    module docstring). ``reset(seed)`` starts the seed's stream of episodes, as the AEC env's."""

    metadata = {"name": "wildfire_v0", "render_modes": list(RENDER_MODES), "render_fps": 4}

    def __init__(self, cfg: WildfireConfig | None = None, render_mode: str | None = None):
        cfg = cfg or WildfireConfig()
        cfg.validate()
        require(render_mode is None or render_mode in RENDER_MODES, "render_mode",
                f"None or one of {', '.join(RENDER_MODES)}", render_mode)
        self.cfg = cfg
        super().__init__(lambda seed: WildfireVectorEnv(cfg, 1, seed), "uav", observation_box(cfg),
                         cfg.n_agents, cfg.n_actions, render_mode)

    def _draw(self, figure) -> None:
        """The state now: fires with their health and status, UAVs with their targets."""
        batch = self._vec.batch
        draw(figure, frame_of_state(batch.env, batch.states[0]), self.cfg)


def parallel_env(cfg: WildfireConfig | None = None,
                 render_mode: str | None = None) -> WildfireParallelEnv:
    """The ParallelEnv."""
    return WildfireParallelEnv(cfg, render_mode)


def raw_env(cfg: WildfireConfig | None = None, render_mode: str | None = None,
            engine: str = "reference") -> WildfireAECEnv:
    """The bare AEC environment."""
    return WildfireAECEnv(cfg, render_mode, engine)


def env(cfg: WildfireConfig | None = None, render_mode: str | None = None,
        engine: str = "reference") -> AECEnv:
    """The AEC environment in PettingZoo's usual wrappers (actions checked, calls in order)."""
    return wrappers.OrderEnforcingWrapper(wrappers.AssertOutOfBoundsWrapper(
        raw_env(cfg, render_mode, engine)))
