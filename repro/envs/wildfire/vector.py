"""The wildfire fast engine as a :class:`repro.core.vector.VectorEnv` (a step API).

It steps one :class:`~repro.envs.wildfire.engine.WildfireBatch`, the engine's rounds, and reads
the ended macro-actions off its decision log: a decision's row is closed once its UAV observed
again (the row is no longer its running one) or its episode ended. Rows reported are dropped from
the log now and then, so that it does not grow with the steps.
"""

from __future__ import annotations

import numpy as np

from repro.core.rollout import DecisionBatch
from repro.core.vector import VectorEnv
from repro.envs.wildfire.engine import WildfireBatch, WildfireEnv
from repro.envs.wildfire.params import EpisodeStream, WildfireConfig


class WildfireVectorEnv(VectorEnv):
    """``n_envs`` wildfire episodes of the stream of ``seed``, stepped (see
    :mod:`repro.core.vector`)."""

    def __init__(self, cfg: WildfireConfig, n_envs: int, seed: int | np.random.SeedSequence):
        self._env = WildfireEnv(cfg)
        super().__init__(n_envs, self._env.obs_dim, self._env.n_actions, self._env.n_agents,
                         self._env.gamma)
        self._seed = seed

    def _start(self) -> None:
        self._stream = EpisodeStream(self._env.cfg, self._seed)
        self._batch = WildfireBatch(self._env, self._stream.draw(self.n_envs))
        self._open = np.zeros(0, np.int64)  # rows answered whose macro-action runs, in order

    def _pending(self) -> DecisionBatch:
        return self._batch.pending()

    def _act(self, actions: np.ndarray) -> tuple[np.ndarray, ...]:
        b = self._batch
        start = b.first
        # the rows before the oldest one still read are reported: drop them when they are a
        # quarter of the log and more than half of it is used (else the log grows as in rollout)
        gone = min(start, self._open[0]) if len(self._open) else start
        if b.used[0] > len(b.log) // 2 and gone >= len(b.log) // 4:
            b.drop(gone)
            self._open -= gone
            start -= gone
        b.act(actions)
        rows = np.concatenate([self._open, np.arange(start, b.first)])
        rec = b.log[rows]
        ep, agent = rec["ep"], rec["agent"]
        over = b.states["done"][ep]
        last = b.states["running_row"][ep, agent] == rows  # the UAV's running (or final) decision
        ended = over | ~last
        self._open = rows[~ended]
        rec, done = rec[ended], (over & last)[ended]
        return (rec["ep"], rec["agent"], rec["idx"], rec["rew"], rec["dur"], done,
                done & b.states["truncated"][rec["ep"]])

    @property
    def batch(self) -> WildfireBatch:
        """The engine's batch being stepped (its episodes' states, for pictures)."""
        return self._batch

    def _finished(self) -> np.ndarray:
        b = self._batch
        over = b.states["done"].copy()
        over[b.log["ep"][b.first:b.used[0]]] = False  # its last decisions await their actions
        return np.flatnonzero(over)

    def _restart(self, slots: np.ndarray) -> None:
        self._batch.restart(slots, self._stream.draw(len(slots)))
