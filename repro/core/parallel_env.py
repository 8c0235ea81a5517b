"""A PettingZoo ``ParallelEnv`` over one episode of a step API (:mod:`repro.core.vector`).

Each ``step`` is one of the engine's rounds: the agents whose decisions are pending now (those
whose events fired at one instant, or, in the wildfire, within one decision latency) act
together, and the episode runs until it is blocked on decisions again. The convention, shared by
both environments and by their AEC wrappers:

- ``agents`` are the agents that have made their first decision and are not done (a bus joins
  at its first arrival at Stop 1). Every dict of a ``step`` holds every agent live before it or
  deciding now, as ``pettingzoo.test.parallel_api_test`` requires (it reads every live agent's
  observation and termination). ``infos[a]["decides"]`` says whether ``a`` has a decision
  pending: an agent whose macro-action runs on shows its latest observation again, with reward
  0 and duration 0, and its action is ignored; a learner keeps only the deciding agents' rows.
  ``step`` takes an action for every deciding agent; actions for other agents are ignored.
- ``rewards[a]`` is the reward of ``a``'s macro-action that ended in this step, discounted within
  the macro-action to its start, exp(-gamma (t - T_k)) per reward at time t: the r_k that M-GAE
  (:mod:`repro.learn.m_gae`) consumes; 0 at an agent's first decision. ``infos[a]`` holds that
  macro-action's ``duration`` dt_k in seconds (0 at a first decision) and ``time``, the clock at
  its end, T_{k+1} = dt_0 + ... + dt_k: the start of the agent's next macro-action, to which its
  next reward is discounted (for an agent not deciding: the start of its running one). An
  agent's first macro-action starts at 0, where every agent's process starts (rewards before its
  first decision are discounted to it). So exp(-gamma T_k) r_k, summed over an agent's
  macro-actions, is its return discounted in continuous time.
- The episode ends at its horizon or by its own dynamics (``terminations``; M-GAE's value after
  the last decision is 0), or is cut at the environment's bound on its length (``truncations``:
  the wildfire's decision limit, ``max_decisions``).
- An agent has one decision pending at a time. (The wildfire engine's rounds may in principle
  hold a UAV's decision superseded within its latency beside its next one; no rollout of the
  tests' policies and settings has shown one, and the env raises if it meets one.)

Observations are float32, as the spaces (bounds the observations reach, tested on rollouts).
"""

from __future__ import annotations

from typing import Callable

import gymnasium
import numpy as np
from pettingzoo import ParallelEnv

from repro.core.canvas import Renders
from repro.core.errors import require
from repro.core.rollout import DecisionBatch
from repro.core.vector import VectorEnv


class EventParallelEnv(Renders, ParallelEnv):
    """One episode of ``make_vector(seed)``'s stream (a one-slot :class:`VectorEnv`) at a time,
    for agents named ``f"{prefix}_{i}"`` (see the module docstring). An environment's subclass
    provides its metadata, spaces and ``_draw``."""

    def __init__(self, make_vector: Callable[[np.random.SeedSequence], VectorEnv], prefix: str,
                 observation_space: gymnasium.spaces.Box, n_agents: int, n_actions: int,
                 render_mode: str | None):
        self._make_vector = make_vector
        self.possible_agents = [f"{prefix}_{i}" for i in range(n_agents)]
        self._obs_space = observation_space
        self._act_space = gymnasium.spaces.Discrete(n_actions)
        self.render_mode = render_mode
        self._seed_seq = np.random.SeedSequence()
        self.agents: list[str] = []

    def observation_space(self, agent: str) -> gymnasium.spaces.Box:
        return self._obs_space

    def action_space(self, agent: str) -> gymnasium.spaces.Discrete:
        return self._act_space

    def reset(self, seed: int | None = None,
              options: dict | None = None) -> tuple[dict, dict]:
        """A new episode (the next of ``seed``'s stream); the first pending decisions."""
        if seed is not None:
            self._seed_seq = np.random.SeedSequence(seed)
        self._vec = self._make_vector(self._seed_seq.spawn(1)[0])
        self._batch = self._vec.reset()
        self._clock = np.zeros(len(self.possible_agents))
        self.agents = []
        obs = self._observations()
        self._last_obs = dict(obs)  # every agent's latest observation
        return obs, {a: {"duration": 0.0, "time": 0.0, "decides": True} for a in obs}

    def _observations(self) -> dict[str, np.ndarray]:
        """The pending decisions' observations; agents deciding for the first time join
        ``agents``."""
        obs = {self.possible_agents[i]: o.astype(np.float32)
               for i, o in zip(self._batch.agent, self._batch.obs)}
        if len(obs) < len(self._batch):
            raise RuntimeError("an agent has two decisions pending at once; the ParallelEnv "
                               "holds one per agent")
        self.agents += [a for a in obs if a not in self.agents]
        return obs

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        """Answer the deciding agents, run the episode until it is blocked again (one round);
        every live agent's observation, reward, termination, truncation and info (see the module
        docstring)."""
        batch = self._batch
        names = [self.possible_agents[i] for i in batch.agent]
        missing = sorted(set(names) - set(actions))
        require(not missing, "actions", "an action for every agent of the last observations",
                f"none for {', '.join(missing)}")
        episode = self._vec.episode[0]
        self._batch, ended = self._vec.step(np.array([int(actions[a]) for a in names]))
        rewards, infos, terms, truncs = {}, {}, {}, {}
        for m in range(len(ended)):
            i = ended.agent[m]
            a = self.possible_agents[i]
            self._clock[i] += ended.duration[m]
            rewards[a] = float(ended.reward[m])
            infos[a] = {"duration": float(ended.duration[m]), "time": float(self._clock[i])}
            terms[a] = bool(ended.done[m] and not ended.truncated[m])
            truncs[a] = bool(ended.truncated[m])
        if self._vec.episode[0] != episode:  # the episode ended: its slot holds the next one
            self._batch = DecisionBatch(np.zeros((0, self._obs_space.shape[0])),
                                        *np.zeros((3, 0), np.int64))
        live = list(self.agents)
        deciding = self._observations()
        self._last_obs.update(deciding)
        obs = {}
        for a in live + [a for a in deciding if a not in live]:
            obs[a] = self._last_obs[a]
            rewards.setdefault(a, 0.0)
            i = self.possible_agents.index(a)
            infos.setdefault(a, {"duration": 0.0, "time": float(self._clock[i])})
            infos[a]["decides"] = a in deciding
            terms.setdefault(a, False)
            truncs.setdefault(a, False)
            if terms[a] or truncs[a]:
                self.agents.remove(a)
        return obs, rewards, terms, truncs, infos

    def close(self) -> None:
        if self._canvas is not None:
            self._canvas.close()
            self._canvas = None
