"""From per-decision records (in any order) to a :class:`Rollout` with contiguous paths."""

from __future__ import annotations

import numpy as np

from repro.core.rollout import Rollout


def rollout_from_records(*, episode: np.ndarray, agent: np.ndarray, index: np.ndarray,
                         time: np.ndarray, obs: np.ndarray, actions: np.ndarray,
                         rewards: np.ndarray, durations: np.ndarray, agent_returns: np.ndarray,
                         end_time: np.ndarray, events: np.ndarray) -> Rollout:
    """Sort the decisions by (episode, agent, index) and group them into paths.

    ``agent_returns`` is (E, N) undiscounted reward sums; an episode's return is their mean.
    ``info`` keeps every decision's observation time, each episode's end time and event count.
    """
    order = np.lexsort((index, agent, episode))
    ep, ag = episode[order], agent[order]
    n_agents = agent_returns.shape[1]
    path_key = ep * n_agents + ag
    first = np.flatnonzero(np.r_[True, path_key[1:] != path_key[:-1]]) if len(order) else \
        np.zeros(0, dtype=np.int64)
    return Rollout(
        obs=obs[order], actions=actions[order].astype(np.int64), rewards=rewards[order],
        durations=durations[order],
        path_start=np.r_[first, len(order)].astype(np.int64),
        path_episode=ep[first].astype(np.int64), path_agent=ag[first].astype(np.int64),
        episode_return=agent_returns.mean(axis=1),
        info={"decision_time": time[order], "end_time": end_time, "events": events},
    )
