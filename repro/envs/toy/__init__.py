"""A tiny event-driven multi-agent problem with a known optimal policy, for testing the learner.

``n_agents`` workers share one reward stream. At each of its decisions a worker sees a job context
c in {0, 1} (one-hot; drawn uniformly, fresh for every decision) and picks a macro-action:

- 0 ``quick``: lasts 1 s, pays 1;
- 1 ``long``: lasts 2 s in context 0 and 4 s in context 1, pays 2.5;
- 2 ``idle``: lasts 1 s, pays 0.

Payments are made when the action starts and, as in the wildfire, every payment is accrued by every
agent into its running macro-action, discounted as exp(-gamma (t - T)) to that action's start T. The
episode ends at ``horizon`` seconds, cutting the running actions. The episode return is the
undiscounted total paid.

The optimum takes durations into account: per decision, ``long`` pays more, but per second it pays
1.25 in context 0 and 0.625 in context 1, so the best policy is long in context 0 and quick in
context 1 (for the default gamma and horizon; :func:`optimal_policy` checks every deterministic
policy exactly). Durations are whole seconds, so all decisions happen on integer times and the
expected discounted return has an exact recursion (:func:`expected_adr`).
"""

from __future__ import annotations

import argparse
import itertools
import math
from dataclasses import dataclass

import numpy as np

from repro.core.config import Validated, add_config_arguments, given_fields
from repro.core.paths import path_layout
from repro.core.rollout import DecisionBatch, Policy, Rollout, episode_streams

TRAIN_DEFAULTS = dict(lam=1.0, batch_episodes=50, epochs=40)
"""Training settings for the toy (small: it is learnt in seconds)."""

N_CONTEXTS = 2
N_ACTIONS = 3
DURATION = np.array([[1, 2, 1], [1, 4, 1]])
"""[context, action] -> duration in whole seconds."""
PAYMENT = np.array([[1.0, 2.5, 0.0], [1.0, 2.5, 0.0]])
"""[context, action] -> payment at the action's start."""


@dataclass(frozen=True)
class ToyConfig(Validated):
    n_agents: int = 2
    """Workers sharing the reward stream."""
    horizon: int = 40
    """Episode length in seconds (a whole number, so the exact recursion applies)."""
    gamma: float = 0.05
    """Continuous-time discount rate (1/s)."""

    def validate(self) -> None:
        self.check(self.n_agents >= 1, "n_agents", "an integer >= 1")
        self.check(self.horizon >= 1, "horizon", "an integer >= 1")
        self.check(self.gamma > 0 and math.isfinite(self.gamma), "gamma", "a number > 0")


class ToyEnv:
    """The :class:`~repro.core.rollout.BatchEnv` of the toy problem: all episodes of a batch advance
    together from one integer decision time to the next."""

    name = "toy"
    obs_dim = N_CONTEXTS
    n_actions = N_ACTIONS

    def __init__(self, cfg: ToyConfig):
        self.cfg = cfg
        self.n_agents = cfg.n_agents
        self.gamma = cfg.gamma

    def rollout(self, policy: Policy, n_episodes: int,
                seed: int | np.random.SeedSequence) -> Rollout:
        e_n, a_n, horizon, gamma = n_episodes, self.n_agents, self.cfg.horizon, self.gamma
        k_max = horizon  # at most one decision per second per agent
        # Episode e draws the contexts of its agents' decisions, in decision order, from its stream.
        contexts = np.stack([np.random.default_rng(ss).integers(0, N_CONTEXTS, (a_n, k_max))
                             for ss in episode_streams(seed, e_n)])
        actions = np.zeros((e_n, a_n, k_max), dtype=np.int64)
        rewards = np.zeros((e_n, a_n, k_max))
        starts = np.zeros((e_n, a_n, k_max))
        count = np.zeros((e_n, a_n), dtype=np.int64)  # decisions made so far
        next_t = np.zeros((e_n, a_n), dtype=np.int64)  # when each agent decides next
        ep_return = np.zeros(e_n)
        ee, aa = np.meshgrid(np.arange(e_n), np.arange(a_n), indexing="ij")
        for t in range(horizon):
            e, a = np.nonzero(next_t == t)
            if len(e):
                k = count[e, a]
                c = contexts[e, a, k]
                act = policy(DecisionBatch(obs=np.eye(N_CONTEXTS)[c], episode=e, agent=a, index=k))
                actions[e, a, k] = act
                starts[e, a, k] = t
                next_t[e, a] = t + DURATION[c, act]
                count[e, a] += 1
                paid = np.bincount(e, weights=PAYMENT[c, act], minlength=e_n)
                ep_return += paid
                # every agent accrues the payments into its running (possibly just started) action
                last = count - 1
                rewards[ee, aa, last] += paid[:, None] * np.exp(-gamma * (t - starts[ee, aa, last]))
        # each action lasts until the agent's next decision; the last one is cut at the horizon
        ends = np.concatenate([starts[..., 1:], np.zeros((e_n, a_n, 1))], axis=2)
        ends[ee, aa, count - 1] = np.minimum(next_t, horizon)
        valid = np.arange(k_max)[None, None, :] < count[..., None]
        obs_c = contexts[valid]
        path_start, path_episode, path_agent = path_layout(count)
        return Rollout(
            obs=np.eye(N_CONTEXTS)[obs_c],
            actions=actions[valid],
            rewards=rewards[valid],
            durations=(ends - starts)[valid],
            path_start=path_start, path_episode=path_episode, path_agent=path_agent,
            episode_return=ep_return,
        )


def expected_adr(cfg: ToyConfig, probs: np.ndarray) -> float:
    """Exact average discounted return of the policy with pi(a | c) = ``probs[c, a]``.

    A path's discounted return weights every payment made at time t by exp(-gamma t), whoever made
    it, so ADR = n_agents * V(0) with V(t) = E_c sum_a pi(a|c) [pay(c,a) + e^{-gamma d(c,a)} V(t+d)]
    and V(t >= horizon) = 0.
    """
    v = np.zeros(cfg.horizon + int(DURATION.max()) + 1)
    for t in range(cfg.horizon - 1, -1, -1):
        q = PAYMENT + np.exp(-cfg.gamma * DURATION) * v[t + DURATION]
        v[t] = float((probs * q).sum(axis=1).mean())
    return cfg.n_agents * float(v[0])


def optimal_policy(cfg: ToyConfig) -> tuple[np.ndarray, float]:
    """The best deterministic policy (action per context) and its exact ADR, by enumeration."""
    best = max(itertools.product(range(N_ACTIONS), repeat=N_CONTEXTS),
               key=lambda acts: expected_adr(cfg, np.eye(N_ACTIONS)[list(acts)]))
    return np.array(best), expected_adr(cfg, np.eye(N_ACTIONS)[list(best)])


def add_env_arguments(parser: argparse.ArgumentParser) -> None:
    """A flag for every :class:`ToyConfig` field."""
    add_config_arguments(parser, ToyConfig)


def config_from_args(args: argparse.Namespace) -> ToyConfig:
    """The validated config of the options of :func:`add_env_arguments` (UsageError if bad)."""
    return ToyConfig(**given_fields(args, ToyConfig))


def make_env(cfg: ToyConfig) -> ToyEnv:
    return ToyEnv(cfg)
