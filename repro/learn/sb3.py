"""Stable-Baselines3's PPO and A2C trained on macro-actions through a PettingZoo ParallelEnv of
this suite (:mod:`repro.core.parallel_env`), with M-GAE (docs/own-learner.md).

- :class:`MGAERolloutBuffer` is SB3's ``RolloutBuffer`` that also stores each decision's
  duration and computes M-GAE (:func:`repro.learn.m_gae.macro_gae`) instead of SB3's GAE; PPO and
  A2C take it as ``rollout_buffer_class`` and train on it with their own optimiser, clipping and
  minibatches (``model.train()``).
- :func:`collect_paths` plays whole episodes of the ParallelEnv (or of several side by side, one
  policy call for the deciding agents of all) with the model's policy and keeps each agent's
  decisions of an episode as one path; :func:`fill_buffer` lays the paths into the
  model's buffer one after another in its single slot (a path start is an episode start; the path
  cut at the buffer's end is bootstrapped with the model's value of its next observation).
- :func:`train_update` is one update: collect, fill, ``model.train()``.

``model.learn`` is not used: SB3 collects by stepping a VecEnv in lockstep, one decision per slot
per step, whereas the agents here decide at their own times; a VecEnv over the agents would invent
steps for the agents whose macro-actions run on. So the paths are collected here and only SB3's
update runs; the buffer's ``add`` takes the durations per slot and step (``durations=``), so a
collector of one's own with more slots fills it the same way.

Requires ``stable-baselines3`` (``pip install -e .[sb3]``).
"""

from __future__ import annotations

import time
from typing import Any, Callable

import gymnasium
import numpy as np
import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.buffers import RolloutBuffer

from repro.learn.m_gae import macro_gae


class MGAERolloutBuffer(RolloutBuffer):
    """SB3's rollout buffer with each decision's duration, whose advantages are M-GAE's.

    ``gamma_rate`` is the environment's continuous-time discount rate (a reward t later weighs
    exp(-gamma_rate t)) and ``lam`` the paper's lambda (>= 0, may exceed 1); SB3's ``gamma`` and
    ``gae_lambda``, which the algorithm passes, are not used. Rewards are each macro-action's,
    discounted to its start (the environments' ``step``). The returns, the value function's
    target, are the discounted returns-to-go R_k (:func:`macro_gae`), as PS-TRPO's baseline's;
    at lam = 1 they equal SB3's advantage + value."""

    def __init__(self, buffer_size: int, observation_space: gymnasium.spaces.Space,
                 action_space: gymnasium.spaces.Space, device: torch.device | str = "auto",
                 gae_lambda: float = 1.0, gamma: float = 0.99, n_envs: int = 1, *,
                 gamma_rate: float, lam: float):
        self.gamma_rate, self.lam = float(gamma_rate), float(lam)
        super().__init__(buffer_size, observation_space, action_space, device,
                         gae_lambda=gae_lambda, gamma=gamma, n_envs=n_envs)

    def reset(self) -> None:
        self.durations = np.zeros((self.buffer_size, self.n_envs))
        super().reset()

    def add(self, *args: Any, durations: np.ndarray | None = None, **kwargs: Any) -> None:
        """SB3's ``add`` and each slot's macro-action duration ``durations`` (shape [n_envs])."""
        if durations is None:
            raise ValueError("durations: must be given with every add (one per env slot)")
        self.durations[self.pos] = np.asarray(durations, dtype=np.float64).reshape(self.n_envs)
        super().add(*args, **kwargs)

    def compute_returns_and_advantage(self, last_values: torch.Tensor, dones: np.ndarray) -> None:
        """M-GAE over the stored decisions: a path ends where the next row starts an episode,
        or at the buffer's end where ``dones``; else it is bootstrapped with ``last_values``."""
        ends = np.zeros((self.buffer_size, self.n_envs), dtype=bool)
        ends[:-1] = self.episode_starts[1:] > 0
        ends[-1] = np.asarray(dones, dtype=bool).reshape(self.n_envs)
        adv, ret = macro_gae(self.rewards, self.durations, self.values,
                             last_values.detach().cpu().numpy().reshape(self.n_envs),
                             self.gamma_rate, self.lam, ends=ends)
        self.advantages[:] = adv
        self.returns[:] = ret


Path = dict[str, list]
"""One agent's decisions of one episode: ``obs``, ``act``, ``value``, ``logp`` (the model's at
each decision), ``rew`` and ``dur`` (each macro-action's reward, discounted to its start, and
duration)."""


def collect_paths(envs: Any, model: BaseAlgorithm, n_decisions: int,
                  seed: int | None = None) -> list[Path]:
    """Whole episodes of the ParallelEnvs ``envs`` (one, or a list played side by side so that
    each policy call serves the deciding agents of all of them) until the finished ones hold
    ``n_decisions`` decisions; the episodes then in flight are played to their end too, so that
    long episodes are not cut out of the batch. Actions are sampled from ``model``'s policy.
    Returns every agent's path of each episode, in the order the episodes ended; a decision made
    at the very instant its episode ended (a macro-action of duration 0 and reward 0, which a
    trained policy meets now and then) is left out, as it changed nothing. ``seed``: each
    env's first reset gets a seed of its own, drawn from it (None: each env's stream goes on)."""
    envs = list(envs) if isinstance(envs, (list, tuple)) else [envs]
    seeds = ([None] * len(envs) if seed is None else
             [int(c.generate_state(1)[0]) for c in np.random.SeedSequence(seed).spawn(len(envs))])
    paths: list[Path] = []
    live = []  # per env in flight: [env, obs, infos, running paths]
    for env, s in zip(envs, seeds):
        live.append([env, *env.reset(seed=s), {}])
    while live:
        rows = [(j, a) for j, (env, obs, infos, _) in enumerate(live)
                for a in obs if infos[a]["decides"] and a in env.agents]
        with torch.no_grad():
            act, value, logp = model.policy(torch.as_tensor(np.stack([live[j][1][a]
                                                                      for j, a in rows])))
        actions: list[dict[str, int]] = [{} for _ in live]
        for m, (j, a) in enumerate(rows):
            path = live[j][3].setdefault(a, {"obs": [], "act": [], "value": [], "logp": [],
                                             "rew": [], "dur": []})
            path["obs"].append(live[j][1][a])
            path["act"].append(int(act[m]))
            path["value"].append(float(value[m]))
            path["logp"].append(float(logp[m]))
            actions[j][a] = int(act[m])
        still = []
        for j, (env, _, _, running) in enumerate(live):
            obs, rewards, terms, truncs, infos = env.step(actions[j])
            for a in obs:  # a macro-action ended: the agent decides again, or its episode ended
                path = running.get(a)
                if path and (infos[a]["decides"] or terms[a] or truncs[a]):
                    path["rew"].append(rewards[a])
                    path["dur"].append(infos[a]["duration"])
                if terms[a] or truncs[a]:
                    path = running.pop(a)
                    if path["dur"][-1] == 0 and path["rew"][-1] == 0:
                        # decided at the instant the episode ended: no time passed, no reward
                        for key in path:
                            path[key].pop()
                    if path["act"]:
                        paths.append(path)
            if env.agents:
                still.append([env, obs, infos, running])
            elif sum(len(p["act"]) for p in paths) < n_decisions:
                still.append([env, *env.reset(), {}])
        live = still
    return paths


def fill_buffer(model: BaseAlgorithm, paths: list[Path]) -> tuple[torch.Tensor, np.ndarray]:
    """Put the paths into ``model``'s rollout buffer (one slot), in order, until it is full (an
    :class:`MGAERolloutBuffer` gets the durations too); returns the arguments of the buffer's
    ``compute_returns_and_advantage``. A path cut at the buffer's end is bootstrapped with the
    value of the observation it continues from; an episode's end has value 0 (PS-TRPO's
    convention, also for the decision limit)."""
    buffer = model.rollout_buffer
    with_durations = isinstance(buffer, MGAERolloutBuffer)
    buffer.reset()
    for path in paths:
        for k in range(len(path["act"])):
            if buffer.full:
                return torch.tensor([path["value"][k]]), np.array([False])
            extra = {"durations": np.array([path["dur"][k]])} if with_durations else {}
            buffer.add(path["obs"][k][None], np.array([[path["act"][k]]]),
                       np.array([path["rew"][k]]), np.array([k == 0]),
                       torch.tensor([path["value"][k]]), torch.tensor([path["logp"][k]]),
                       **extra)
    return torch.zeros(1), np.array([True])


def path_adr(paths: list[Path], gamma_rate: float) -> float:
    """Average discounted return of ``paths``: each reward weighed by exp(-gamma T_k), T_k its
    macro-action's start."""
    return float(np.mean([np.sum(np.exp(-gamma_rate * (np.cumsum(p["dur"]) - np.array(p["dur"])))
                                 * np.array(p["rew"])) for p in paths]))


def train_update(envs: Any, model: BaseAlgorithm, seed: int | None = None,
                 on_batch: Callable[[list[Path]], None] | None = None
                 ) -> tuple[list[Path], dict[str, float]]:
    """One update of ``model`` (PPO or A2C, with either buffer) on a fresh batch of
    ``model.n_steps`` decisions of ``envs`` (:func:`collect_paths`, with ``seed``; ``on_batch`` sees
    the paths before the advantages are computed): the batch's paths, and the CPU seconds of its
    parts (``collect``, ``advantages``: the buffer's ``compute_returns_and_advantage``, ``train``:
    SB3's update)."""
    t0 = time.process_time()
    paths = collect_paths(envs, model, model.n_steps, seed)
    if on_batch is not None:
        on_batch(paths)
    collected = time.process_time() - t0
    fill, advantages, train = update_on(model, paths)
    return paths, {"collect": collected + fill, "advantages": advantages, "train": train}


def update_on(model: BaseAlgorithm, paths: list[Path]) -> tuple[float, float, float]:
    """Fill ``model``'s buffer with ``paths``, compute its advantages and run SB3's update; the
    CPU seconds of each of the three."""
    t0 = time.process_time()
    last_values, dones = fill_buffer(model, paths)
    t1 = time.process_time()
    model.rollout_buffer.compute_returns_and_advantage(last_values, dones)
    t2 = time.process_time()
    model.train()
    return t1 - t0, t2 - t1, time.process_time() - t2


class Spaces(gymnasium.Env):
    """What SB3's constructors read of an environment: its spaces (the ParallelEnv's, one
    agent's). It is never stepped: :func:`collect_paths` steps the ParallelEnv."""

    def __init__(self, parallel: Any):
        agent = parallel.possible_agents[0]
        self.observation_space = parallel.observation_space(agent)
        self.action_space = parallel.action_space(agent)

    def reset(self, *, seed=None, options=None):
        raise NotImplementedError("the ParallelEnv is stepped directly: see collect_paths")

    def step(self, action):
        raise NotImplementedError("the ParallelEnv is stepped directly: see collect_paths")


def as_policy(model: BaseAlgorithm):
    """``model``'s policy as a ``repro`` policy (a batch of decisions -> actions), sampling: for
    the environments' ``rollout`` and the suite's evaluation."""
    def act(batch):
        with torch.no_grad():
            actions, _, _ = model.policy(torch.as_tensor(batch.obs, dtype=torch.float32))
        return actions.numpy().astype(np.int64)
    return act
