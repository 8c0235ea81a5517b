"""A step API over an event-driven batch engine: ``reset`` and ``step`` on ``n_envs`` episodes.

A :class:`VectorEnv` holds ``n_envs`` episodes in slots (env indices 0..n_envs-1). ``reset()``
starts episodes 0..n_envs-1 of the seed's stream (:func:`repro.core.rollout.episode_streams`'s
order: episode k here is episode k of ``rollout(policy, n, seed)`` for every n > k) and returns
every pending decision, one :class:`DecisionBatch` whose ``episode`` column is the env index.
``step(actions)`` answers every row of that batch, runs every episode until it is blocked on a
decision again, and returns the new pending decisions and the :class:`Transitions`: the
macro-actions that ended. An episode that ends is replaced in its slot by the next episode of the
stream, whose first decisions are in the same returned batch; if the ended episode still has
decisions pending (wildfire UAVs may observe at the very instant it ends, and the rollout records
those decisions too), they are answered first and the slot restarts one step later.

Driven with a policy, a vector env makes exactly the decisions, observations, rewards and
durations of ``rollout`` for the same episodes: an engine's rounds (run every live episode until
blocked, then ask for every pending decision at once) are the steps, and an episode's dynamics do
not depend on the others in its batch.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from repro.core.errors import require
from repro.core.rollout import DecisionBatch


@dataclass(frozen=True)
class Transitions:
    """The macro-actions that ended in one step, one row each.

    A macro-action is reported once it has ended and its action was given: one that ends before
    the policy answered it (wildfire: a UAV interrupted within its decision latency) is reported
    by the step that answers it. Its reward and duration are those of the rollout (see
    :class:`repro.core.rollout.Rollout`)."""

    env: np.ndarray
    """(T,) int64 env index (slot) of the macro-action's episode."""
    episode: np.ndarray
    """(T,) int64 number of that episode in the seed's stream (0, 1, ...)."""
    agent: np.ndarray
    """(T,) int64 agent index within the episode."""
    index: np.ndarray
    """(T,) int64 decision number k of the macro-action along its agent's path (as in
    :attr:`DecisionBatch.index`)."""
    reward: np.ndarray
    """(T,) float64 reward r_k, discounted within the macro-action to its start."""
    duration: np.ndarray
    """(T,) float64 duration dt_k in seconds."""
    done: np.ndarray
    """(T,) bool: the episode ended during this macro-action (the agent's last of the episode);
    the env's next decisions are the next episode's."""
    truncated: np.ndarray
    """(T,) bool: ``done``, and the episode was cut at the environment's bound on its length (the
    wildfire's decision limit, :attr:`repro.core.rollout.Rollout.truncated`), not ended by its own
    dynamics or its horizon."""

    def __len__(self) -> int:
        return len(self.env)


class VectorEnv(ABC):
    """``n_envs`` episodes of one engine, driven step by step (see the module docstring). An
    engine's subclass provides the four hooks; this class keeps the episode numbers."""

    def __init__(self, n_envs: int, obs_dim: int, n_actions: int, n_agents: int, gamma: float):
        require(isinstance(n_envs, (int, np.integer)) and n_envs >= 1, "n_envs",
                "an integer >= 1", n_envs)
        self.n_envs = int(n_envs)
        self.obs_dim, self.n_actions, self.n_agents = obs_dim, n_actions, n_agents
        self.gamma = gamma
        self.episode = np.zeros(0, np.int64)
        """(n_envs,) the stream number of every slot's episode (empty before ``reset``)."""
        self._next = 0

    def reset(self) -> DecisionBatch:
        """Start episodes 0..n_envs-1 of the stream; their first decisions."""
        self.episode = np.arange(self.n_envs, dtype=np.int64)
        self._next = self.n_envs
        self._start()
        return self._pending()

    def step(self, actions: np.ndarray) -> tuple[DecisionBatch, Transitions]:
        """Answer every row of the last batch (one integer action each); the next batch, and the
        macro-actions that ended."""
        require(len(self.episode) == self.n_envs, "step", "called after reset()", "before")
        env, agent, index, reward, duration, done, truncated = self._act(np.asarray(actions))
        ended = Transitions(env=env, episode=self.episode[env], agent=agent, index=index,
                            reward=reward, duration=duration, done=done, truncated=truncated)
        slots = self._finished()
        if len(slots):
            self._restart(slots)
            self.episode[slots] = np.arange(self._next, self._next + len(slots))
            self._next += len(slots)
        return self._pending(), ended

    @abstractmethod
    def _start(self) -> None:
        """Start the stream's first n_envs episodes in slots 0..n_envs-1."""

    @abstractmethod
    def _pending(self) -> DecisionBatch:
        """Every pending decision (rows in the engine's round order)."""

    @abstractmethod
    def _act(self, actions: np.ndarray) -> tuple[np.ndarray, ...]:
        """Answer the pending decisions and run until blocked; the macro-actions now reportable
        (see :class:`Transitions`) as (env, agent, index, reward, duration, done, truncated)
        columns."""

    @abstractmethod
    def _finished(self) -> np.ndarray:
        """The slots whose episode has ended and has no decision pending, in increasing order."""

    @abstractmethod
    def _restart(self, slots: np.ndarray) -> None:
        """Start the stream's next len(slots) episodes in ``slots``, in that order."""
