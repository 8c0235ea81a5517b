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
from repro.envs.wildfire.engine import WildfireBatch, WildfireEnv, jit
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
        n = len(self._open) + b.first - start
        ids, values, flags, still_open = (np.empty((3, n), np.int64), np.empty((2, n)),
                                          np.empty((2, n), np.bool_), np.empty(n, np.int64))
        m, k = _closed(b.states, b.log, self._open, start, b.first, ids, values, flags,
                       still_open)
        self._open = still_open[:k]
        return (ids[0, :m], ids[1, :m], ids[2, :m], values[0, :m], values[1, :m], flags[0, :m],
                flags[1, :m])

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


@jit
def _closed(states, log, open_rows, start, stop, ids, values, flags, still_open):
    """The rows the step answered, ``open_rows`` (answered before, their macro-action running)
    then ``start``..``stop`` (answered now), in that order. A row is closed once its episode is
    over or it is no longer its UAV's running row (the UAV observed again). Closed rows go, in
    order, into the columns of ``ids`` (episode, agent, index), ``values`` (reward, duration) and
    ``flags`` (done: the episode is over and the row is its UAV's last; truncated: done in a
    truncated episode); the others into ``still_open``. Returns both counts. One compiled pass:
    gathering whole log rows (observations included) with numpy cost more than the round."""
    m = k = 0
    for q in range(len(open_rows) + stop - start):
        row = open_rows[q] if q < len(open_rows) else start + q - len(open_rows)
        record = log[row]
        state = states[record.ep]
        last = state.running_row[record.agent] == row
        if state.done or not last:
            ids[0, m], ids[1, m], ids[2, m] = record.ep, record.agent, record.idx
            values[0, m], values[1, m] = record.rew, record.dur
            flags[0, m] = state.done and last
            flags[1, m] = flags[0, m] and state.truncated
            m += 1
        else:
            still_open[k] = row
            k += 1
    return m, k
