"""Decisions packed into paths, as every engine's :class:`repro.core.rollout.Rollout` holds them.

A batch of E episodes of N agents has E N paths: path p = e N + i holds agent i's decisions in
episode e, numbered k = 0, 1, ... in the order it made them, and the paths lie one after another.
:func:`path_layout` gives that layout from the decision counts; an engine that records decisions
interleaved (as they happen) finds each one's place with :func:`path_order` and gathers its
columns in that order.
"""

from __future__ import annotations

import numpy as np
from numba import njit


def path_layout(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``path_start`` (E N + 1,), ``path_episode`` and ``path_agent`` (E N,), all int64, of the
    paths of (E, N) decision ``counts`` (path e N + i: agent i of episode e)."""
    n_episodes, n_agents = counts.shape
    path_start = np.zeros(n_episodes * n_agents + 1, np.int64)
    np.cumsum(counts.reshape(-1), out=path_start[1:])
    return (path_start, np.repeat(np.arange(n_episodes, dtype=np.int64), n_agents),
            np.tile(np.arange(n_agents, dtype=np.int64), n_episodes))


@njit(cache=True)
def path_order(episode, agent, index, n_agents, path_start):
    """(D,) int64: the row of every decision in path order, from each row's episode, agent and
    decision number. A row's place is its path's start plus its number, so rows may come in any
    order and no sort is needed (gathering the rows in this order then reads scattered rows, which
    beats writing them). ValueError unless the numbers of every path are 0, 1, ... each once and
    the rows fill ``path_start`` exactly."""
    n_rows = len(episode)
    if n_rows != path_start[-1]:
        raise ValueError("the rows do not fill the paths")
    order = np.full(n_rows, -1, np.int64)
    for row in range(n_rows):
        path = episode[row] * n_agents + agent[row]
        start = path_start[path]
        k = index[row]
        if k < 0 or k >= path_start[path + 1] - start or order[start + k] >= 0:
            raise ValueError("each path's decisions must be numbered 0, 1, ..., each once")
        order[start + k] = row
    return order
