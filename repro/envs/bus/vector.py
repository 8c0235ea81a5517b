"""The bus fast engine as a :class:`repro.core.vector.VectorEnv` (a step API).

It steps one :class:`~repro.envs.bus.engine.BusBatch`, the engine's rounds. A bus's macro-action
ends when it observes again (its next decision) or at the horizon, and a bus has a decision only
once its previous one was answered, so every ended macro-action is reportable at once. The
environment is deterministic: every episode of the stream is the same, and ``seed`` is unused, as
in ``rollout``. Its episodes end at the horizon, never truncated.
"""

from __future__ import annotations

import numpy as np

from repro.core.rollout import DecisionBatch
from repro.core.vector import VectorEnv
from repro.envs.bus.engine import OBS_DIM, BusBatch
from repro.envs.bus.params import BusConfig


class BusVectorEnv(VectorEnv):
    """``n_envs`` bus episodes, stepped (see :mod:`repro.core.vector`)."""

    def __init__(self, cfg: BusConfig, n_envs: int, seed: int | np.random.SeedSequence = 0):
        self.cfg = cfg
        super().__init__(n_envs, OBS_DIM, cfg.n_actions, cfg.n_buses, cfg.gamma)

    def _start(self) -> None:
        self._batch = BusBatch(self.cfg, self.n_envs)
        self._batch.advance(np.zeros(0, np.int64))

    def _pending(self) -> DecisionBatch:
        return self._batch.decisions()

    def _act(self, actions: np.ndarray) -> tuple[np.ndarray, ...]:
        b = self._batch
        was_over = b.done
        b.advance(actions)
        env, agent, index, reward, duration, done = b.ended(was_over)
        return env, agent, index, reward, duration, done, np.zeros(len(env), bool)

    @property
    def batch(self) -> BusBatch:
        """The engine's batch being stepped (its episodes' states, for pictures)."""
        return self._batch

    def _finished(self) -> np.ndarray:
        return np.flatnonzero(self._batch.done)

    def _restart(self, slots: np.ndarray) -> None:
        self._batch.restart(slots)
