"""The step API (repro.core.vector) makes exactly rollout's decisions, rewards and durations."""

from __future__ import annotations

import numpy as np
import pytest

from repro.core.errors import UsageError
from repro.envs import env_package, make_vector_env

CASES = [
    ("wildfire", {}),  # ED
    ("wildfire", {"dt": 1.0}),  # FS
    ("wildfire", {"dt": 10 ** 0.5, "same_instant_order": "scheduling", "max_decisions": 3}),
    ("bus", {}),
]


def fast_env(name: str, config: dict):
    module = env_package(name)
    return module.make_env((module.WildfireConfig if name == "wildfire" else module.BusConfig)(
        **config))


def by_obs(obs: np.ndarray, n_actions: int) -> np.ndarray:
    """A deterministic policy that acts on what it sees (its actions vary row by row)."""
    return (np.floor(np.abs(obs).sum(axis=1) * 1000) % n_actions).astype(np.int64)


class SplitPolicy:
    """A stochastic policy: rows of the stream's first ``n_first`` episodes draw from one seeded
    Generator in row order, other rows from another. Rollout's rounds and the vector env's steps
    hold the first episodes' rows in the same order, so the first Generator is consumed
    identically by both."""

    def __init__(self, n_actions: int, n_first: int):
        self.n_actions, self.n_first = n_actions, n_first
        self.mine, self.other = np.random.default_rng(11), np.random.default_rng(12)

    def __call__(self, batch, episode: np.ndarray) -> np.ndarray:
        first = episode < self.n_first
        u = np.empty(len(batch))
        u[first] = self.mine.random(int(first.sum()))
        u[~first] = self.other.random(int((~first).sum()))
        return (u * self.n_actions).astype(np.int64)


def rollout_table(rollout) -> dict:
    """(episode, agent, k) -> (obs, action, reward, duration, last of its path, last of its path
    in a truncated episode)."""
    table = {}
    step = rollout.step_index()
    path = rollout.path_index()
    last = np.zeros(rollout.n_decisions, bool)
    last[rollout.path_start[1:][np.diff(rollout.path_start) > 0] - 1] = True
    truncated = (np.zeros(len(rollout.episode_return), bool) if rollout.truncated is None
                 else rollout.truncated)
    for d in range(rollout.n_decisions):
        p = path[d]
        episode = rollout.path_episode[p]
        table[(episode, rollout.path_agent[p], step[d])] = (
            tuple(rollout.obs[d]), rollout.actions[d], rollout.rewards[d], rollout.durations[d],
            last[d], last[d] and truncated[episode])
    return table


def step_table(vec, act, n_episodes: int) -> dict:
    """Drive ``vec`` until the stream's first ``n_episodes`` episodes have ended; the same table
    as :func:`rollout_table` for them."""
    decided, ended = {}, {}
    batch = vec.reset()
    while vec.episode.min() < n_episodes:
        episode = vec.episode[batch.episode]
        actions = act(batch, episode)
        for m in range(len(batch)):
            decided[(episode[m], batch.agent[m], batch.index[m])] = (tuple(batch.obs[m]),
                                                                      actions[m])
        batch, tr = vec.step(actions)
        for m in range(len(tr)):
            key = (tr.episode[m], tr.agent[m], tr.index[m])
            assert key in decided and key not in ended  # reported once, after its action
            assert vec.episode[tr.env[m]] >= tr.episode[m]
            ended[key] = (tr.reward[m], tr.duration[m], tr.done[m], tr.truncated[m])
    return {k: decided[k] + ended[k] for k in decided if k[0] < n_episodes}


@pytest.mark.parametrize("name, config", CASES)
def test_steps_make_rollouts_decisions_with_a_stochastic_policy(name, config):
    n = 6 if name == "wildfire" else 3
    vec = make_vector_env(name, n, 5, **config)
    ref = SplitPolicy(vec.n_actions, n)
    want = rollout_table(fast_env(name, config).rollout(lambda b: ref(b, b.episode), n, 5))
    got = step_table(vec, SplitPolicy(vec.n_actions, n), n)
    assert got.keys() == want.keys()
    assert got == want


@pytest.mark.parametrize("name, config, n", [
    ("wildfire", {"max_decisions": 30}, 10),
    ("wildfire", {"dt": 1.0}, 60),
    # a long latency: episodes end while decisions are pending, their slots restart a step later
    ("wildfire", {"decision_latency": 5.0, "max_decisions": 30}, 40),
    ("bus", {}, 5)])
def test_later_episodes_of_the_stream_are_rollouts_episodes(name, config, n):
    """With 3 envs, episodes 3.. run in restarted slots: still episode k of the stream (a limit
    on decisions: this policy makes UAVs stay in ED for millions of decisions)."""
    vec = make_vector_env(name, 3, 9, **config)
    want = rollout_table(fast_env(name, config).rollout(lambda b: by_obs(b.obs, vec.n_actions),
                                                        n, 9))
    got = step_table(vec, lambda b, episode: by_obs(b.obs, vec.n_actions), n)
    assert got == want
    if n == 60:  # reported rows leave the decision log: it keeps its first size
        assert len(want) > 4000
        assert len(vec._batch.log) == 1024


def test_bad_use_is_refused():
    vec = make_vector_env("wildfire", 2, 0)
    with pytest.raises(UsageError):
        vec.step(np.zeros(0, np.int64))  # before reset
    batch = vec.reset()
    with pytest.raises(ValueError, match="integer actions"):
        vec.step(np.zeros(len(batch) + 1, np.int64))
    with pytest.raises(UsageError):
        make_vector_env("toy", 2, 0)
    with pytest.raises(UsageError):
        make_vector_env("bus", 0, 0)
