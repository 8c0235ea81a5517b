"""The contract between event-driven engines and everything that consumes them.

An engine simulates a batch of episodes. Whenever agents must act it hands the policy one
:class:`DecisionBatch` holding every pending decision of the whole batch, and receives one action
per row. When all episodes have ended it returns a :class:`Rollout`: the decisions grouped into
*paths* (one agent in one episode), each path's decisions contiguous and in time order.

Per decision k of a path the rollout keeps the observation o_k, the action a_k, the macro-action's
reward r_k (rewards accrued during the action at time t, discounted to the action's start T_k as
exp(-gamma (t - T_k)) reward) and its duration dt_k (time from its start to the next observation, or
to the end of the episode for the last one).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Protocol, runtime_checkable

import numpy as np


class BadActions(ValueError):
    """A policy's answer that is not one integer action in [0, n_actions) per pending decision:
    every engine raises this, and nothing of the round is changed."""

    def __init__(self, answer: np.ndarray, n: int, n_actions: int):
        super().__init__(f"policy must return {n} integer actions in [0, {n_actions}), got "
                         f"shape {answer.shape} dtype {answer.dtype}")


def check_actions(actions: np.ndarray, n: int, n_actions: int,
                  check_range: bool = True) -> np.ndarray:
    """The policy's answer as contiguous (n,) int64 actions (no copy when it is one already), or
    :class:`BadActions`. ``check_range=False`` leaves the range to a compiled kernel (numpy's min
    and max cost more than a small round)."""
    a = np.asarray(actions)
    if a.shape != (n,) or a.dtype.kind not in "iu" or (check_range and a.size and (
            a.min() < 0 or a.max() >= n_actions)):
        raise BadActions(a, n, n_actions)
    return np.ascontiguousarray(a, dtype=np.int64)


@dataclass(frozen=True)
class DecisionBatch:
    """The decisions an engine needs now: one row per agent waiting to act."""

    obs: np.ndarray
    """(M, obs_dim) float64 observations."""
    episode: np.ndarray
    """(M,) int64 index of each row's episode within the batch."""
    agent: np.ndarray
    """(M,) int64 agent index within its episode."""
    index: np.ndarray
    """(M,) int64 decision number k of that agent in that episode (0 for its first)."""

    def __len__(self) -> int:
        return len(self.episode)


Policy = Callable[[DecisionBatch], np.ndarray]
"""Maps a batch of pending decisions to one integer action per row."""


@dataclass
class Rollout:
    """The recorded decisions of a batch of episodes."""

    obs: np.ndarray
    """(D, obs_dim) observation of every decision."""
    actions: np.ndarray
    """(D,) int64 action of every decision."""
    rewards: np.ndarray
    """(D,) macro-action reward r_k, discounted within the macro-action to its start. Rewards an
    agent gets before its first decision (a bus queueing for Stop 1) go into its first
    macro-action, discounted to t = 0, where every agent's process starts."""
    durations: np.ndarray
    """(D,) macro-action duration dt_k in seconds."""
    path_start: np.ndarray
    """(P+1,) int64 offsets: path p holds decisions path_start[p]:path_start[p+1]."""
    path_episode: np.ndarray
    """(P,) episode of each path."""
    path_agent: np.ndarray
    """(P,) agent of each path."""
    episode_return: np.ndarray
    """(E,) the environment's undiscounted return of each episode (defined by the environment)."""
    truncated: np.ndarray | None = None
    """(E,) bool: the episode was cut at the environment's bound on its length (the wildfire's
    decision limit), not ended by its own dynamics. None: the environment has no such bound (its
    episodes end at a horizon they reach in a bounded number of decisions)."""
    info: dict[str, Any] = field(default_factory=dict)
    """Engine-specific extras (for example event counts), never needed by the learner."""

    @property
    def n_decisions(self) -> int:
        return len(self.actions)

    @property
    def n_truncated(self) -> int:
        """Episodes cut at the environment's bound on their length."""
        return 0 if self.truncated is None else int(self.truncated.sum())

    @property
    def n_paths(self) -> int:
        return len(self.path_agent)

    def path_index(self) -> np.ndarray:
        """(D,) the path of every decision."""
        return np.repeat(np.arange(self.n_paths), np.diff(self.path_start))

    def step_index(self) -> np.ndarray:
        """(D,) every decision's number k = 0, 1, ... along its own path."""
        starts = self.path_start[:-1]
        return np.arange(self.n_decisions) - np.repeat(starts, np.diff(self.path_start))

    def discounted_path_returns(self, gamma: float) -> np.ndarray:
        """(P,) R = r_0 + e^{-gamma dt_0}(r_1 + e^{-gamma dt_1}(r_2 + ...)) for every path."""
        return discounted_path_returns(self.rewards, self.durations, self.path_start, gamma)


def head(rollout: Rollout, n_episodes: int) -> Rollout:
    """The first ``n_episodes`` episodes of ``rollout`` (whose paths are in episode order, as every
    engine packs them); ``info`` is not kept."""
    n_paths = int(np.searchsorted(rollout.path_episode, n_episodes))
    if n_paths < rollout.n_paths and not (rollout.path_episode[n_paths:] >= n_episodes).all():
        raise ValueError("the rollout's paths are not in episode order")
    d = int(rollout.path_start[n_paths])
    return Rollout(obs=rollout.obs[:d], actions=rollout.actions[:d], rewards=rollout.rewards[:d],
                   durations=rollout.durations[:d], path_start=rollout.path_start[:n_paths + 1],
                   path_episode=rollout.path_episode[:n_paths],
                   path_agent=rollout.path_agent[:n_paths],
                   episode_return=rollout.episode_return[:n_episodes],
                   truncated=None if rollout.truncated is None else rollout.truncated[:n_episodes])


def discounted_path_returns(rewards: np.ndarray, durations: np.ndarray, path_start: np.ndarray,
                            gamma: float) -> np.ndarray:
    """Each path's return discounted in continuous time to the path's start.

    Decision k of a path starts at T_k = dt_0 + ... + dt_{k-1}, so its reward is weighted by
    exp(-gamma T_k); a cumulative sum per path gives all T_k at once.
    """
    lengths = np.diff(path_start)
    t_end = np.cumsum(durations)
    path_t0 = np.concatenate([[0.0], t_end])[path_start[:-1]]
    t_start = t_end - durations - np.repeat(path_t0, lengths)
    weighted = np.exp(-gamma * t_start) * rewards
    sums = np.add.reduceat(weighted, path_start[:-1]) if len(weighted) else np.zeros(0)
    return np.where(lengths > 0, sums, 0.0)


def concat(rollouts: list[Rollout]) -> Rollout:
    """Join rollouts of separate batches (episode indices are renumbered to stay unique)."""
    offs, ep_offs, starts, eps = 0, 0, [np.zeros(1, dtype=np.int64)], []
    for r in rollouts:
        starts.append(r.path_start[1:] + offs)
        eps.append(r.path_episode + ep_offs)
        offs += r.n_decisions
        ep_offs += len(r.episode_return)
    return Rollout(
        obs=np.concatenate([r.obs for r in rollouts]),
        actions=np.concatenate([r.actions for r in rollouts]),
        rewards=np.concatenate([r.rewards for r in rollouts]),
        durations=np.concatenate([r.durations for r in rollouts]),
        path_start=np.concatenate(starts),
        path_episode=np.concatenate(eps),
        path_agent=np.concatenate([r.path_agent for r in rollouts]),
        episode_return=np.concatenate([r.episode_return for r in rollouts]),
        truncated=(None if all(r.truncated is None for r in rollouts) else np.concatenate(
            [np.zeros(len(r.episode_return), bool) if r.truncated is None else r.truncated
             for r in rollouts])),
    )


def children(seed: int | np.random.SeedSequence, n: int) -> list[np.random.SeedSequence]:
    """The ``n`` children ``seed.spawn(n)`` would give, without advancing ``seed``: ``spawn`` moves
    a SeedSequence on, so handing the same object to a function twice would otherwise give other
    draws the second time, where the same int seed gives the same."""
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    return np.random.SeedSequence(ss.entropy, spawn_key=ss.spawn_key, pool_size=ss.pool_size,
                                  n_children_spawned=ss.n_children_spawned).spawn(n)


def episode_streams(seed: int | np.random.SeedSequence,
                    n_episodes: int) -> list[np.random.SeedSequence]:
    """One independent random stream per episode of a batch.

    Both engines of an environment (SimPy reference and fast) draw episode ``e``'s randomness from
    ``episode_streams(seed, n)[e]`` in the same order, which is what makes them comparable draw by
    draw. The policy's own randomness is separate (the policy owns its generator).
    """
    return children(seed, n_episodes)


DECISION_BYTES = 56
"""Bytes a rollout records per decision besides its observation: action, reward, duration, and the
engine's episode, agent and decision numbers while the paths are packed."""


def rollout_bytes(env: Any, n_episodes: int, *, keep_obs: bool = True,
                  batch: int | None = None) -> int:
    """A lower bound of the memory a rollout of ``n_episodes`` holds: per episode what the engine
    holds besides its decisions (``episode_bytes``, where the engine says; for ``batch`` episodes
    at a time if they run in batches), and per agent at least one decision (with its
    observation, if kept). For up-front checks of sizes (:func:`repro.runs.memory.
    require_memory`)."""
    at_once = n_episodes if batch is None else min(n_episodes, batch)
    per_decision = DECISION_BYTES + (8 * env.obs_dim if keep_obs else 0)
    return (at_once * int(getattr(env, "episode_bytes", 0))
            + n_episodes * env.n_agents * per_decision)


class BatchEnv(Protocol):
    """What the learner and the evaluation tools need from an event-driven multi-agent environment.

    Every environment package ``repro.envs.<name>`` provides one of these (its fast engine) through
    ``make_env(config)``, and its SimPy reference through ``make_reference_env(config)``.
    """

    name: str
    obs_dim: int
    n_actions: int
    n_agents: int
    gamma: float
    """Continuous-time discount rate (1/s) used inside macro-actions and by M-GAE."""

    def rollout(self, policy: Policy, n_episodes: int,
                seed: int | np.random.SeedSequence) -> Rollout:
        """Simulate ``n_episodes`` whole episodes, asking ``policy`` for every decision."""
        ...


@runtime_checkable
class RunsOnDraws(Protocol):
    """A :class:`BatchEnv` whose episodes' own randomness is a fixed number of uniforms each, and
    which runs episodes on given draws: what the released pool needs of an environment that draws
    random numbers itself (:mod:`repro.learn.pool`; one that draws none is a :class:`RunsToEnd`).
    The wildfire's engines are both."""

    draws_per_episode: int
    """Uniforms on [0, 1) every episode takes, whatever happens in it."""

    def episode_draws(self, uniforms: np.ndarray) -> Any:
        """The draws of the episodes whose uniforms are the rows of the (E, draws_per_episode)
        ``uniforms``, as :meth:`simulate` takes them."""
        ...

    def simulate(self, policy: Policy, draws: Any) -> Rollout:
        """Run the episodes of ``draws``, asking ``policy`` for every decision."""
        ...


class RoundBatch(Protocol):
    """A batch of episodes advanced round by round: ``advance`` answers the pending decisions
    (none, the first time) and returns the next ones, empty once every episode has ended."""

    def advance(self, actions: np.ndarray) -> DecisionBatch: ...

    def to_rollout(self) -> Rollout: ...


def run_to_end(batch: RoundBatch, policy: Policy) -> None:
    """Run a round batch to the end: one policy call per round."""
    decisions = batch.advance(np.zeros(0, np.int64))
    while len(decisions):
        decisions = batch.advance(np.asarray(policy(decisions)))


class RunsToEnd:
    """Mixin of a deterministic :class:`BatchEnv` whose ``start(n_episodes)`` gives a
    :class:`RoundBatch`: ``rollout`` runs it to the end. ``seed`` is unused (only the policy is
    random)."""

    def rollout(self, policy: Policy, n_episodes: int,
                seed: int | np.random.SeedSequence = 0) -> Rollout:
        batch = self.start(n_episodes)  # type: ignore[attr-defined]
        run_to_end(batch, policy)
        return batch.to_rollout()
