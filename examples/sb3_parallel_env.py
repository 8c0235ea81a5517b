"""Stable-Baselines3's PPO trains one shared policy on the wildfire through the PettingZoo
ParallelEnv (``repro.envs.wildfire.pettingzoo_env.parallel_env``).

What it does: it plays whole episodes of the ParallelEnv, sampling every deciding UAV's action
from SB3's policy (``infos[uav]["decides"]``: a UAV whose macro-action runs on is not asked), and
keeps every UAV's decisions of an episode as one path, with the rewards the env hands out: each
macro-action's rewards discounted to its start (M-GAE's r_k). The paths fill SB3's
``RolloutBuffer`` one after another (a path start is an episode start; the path cut at the
buffer's end is bootstrapped with SB3's value of its next observation; the rest of the batch is
dropped), and ``PPO.train`` updates the policy and value network: SB3's own GAE, clipped
objective, optimiser and minibatches. ``model.learn`` is not used: SB3's rollout collection steps
a vector env in lockstep, one observation per slot, whereas here the UAVs decide at their own
times (an SB3 VecEnv over the agents would invent steps for the UAVs in flight).

What it does not do: SB3's GAE discounts per decision, by one gamma_d, so it ignores the
macro-actions' durations. It uses gamma_d = exp(-gamma m) and lambda_d = exp(-gamma (lam - 1) m),
m the first batch's mean macro-action duration: the ``decision-gae`` estimator of
:mod:`repro.learn.m_gae` (claim X1), not the paper's M-GAE, whose discount exp(-gamma dt_k)
follows each macro-action's duration. Nor is it PS-TRPO (no trust region, Adam instead of
natural gradient steps), and ADR here is measured on test episodes of the fast engine with the
policy sampling, as ``repro``'s evaluation does.

    python examples/sb3_parallel_env.py --updates 20 --n-steps 10000
"""

from __future__ import annotations

import argparse

import gymnasium
import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.logger import configure

from repro.envs.wildfire import WildfireConfig, make_env
from repro.envs.wildfire.pettingzoo_env import parallel_env
from repro.studies.wildfire.study import adr


class Spaces(gymnasium.Env):
    """What PPO's constructor reads of an environment: its spaces (the ParallelEnv's)."""

    def __init__(self, observation_space: gymnasium.spaces.Box,
                 action_space: gymnasium.spaces.Discrete):
        self.observation_space, self.action_space = observation_space, action_space

    def reset(self, *, seed=None, options=None):
        raise NotImplementedError("the ParallelEnv is stepped directly; see collect()")

    def step(self, action):
        raise NotImplementedError("the ParallelEnv is stepped directly; see collect()")


def collect(env, model: PPO, n_decisions: int) -> list[dict[str, list]]:
    """Whole episodes until they hold ``n_decisions`` decisions: every agent's path of each."""
    paths: list[dict[str, list]] = []
    while sum(len(p["act"]) for p in paths) < n_decisions:
        obs, infos = env.reset()
        running: dict[str, dict[str, list]] = {}
        while env.agents:
            deciding = [a for a in obs if infos[a]["decides"] and a in env.agents]
            with torch.no_grad():
                act, value, logp = model.policy(torch.as_tensor(np.stack([obs[a]
                                                                          for a in deciding])))
            for m, a in enumerate(deciding):
                path = running.setdefault(a, {"obs": [], "act": [], "value": [], "logp": [],
                                              "rew": [], "dur": []})
                path["obs"].append(obs[a])
                path["act"].append(int(act[m]))
                path["value"].append(float(value[m]))
                path["logp"].append(float(logp[m]))
            obs, rewards, terms, truncs, infos = env.step(
                {a: running[a]["act"][-1] for a in deciding})
            for a in obs:  # a macro-action ended: the agent decides again, or its episode ended
                path = running.get(a)
                if path and (infos[a]["decides"] or terms[a] or truncs[a]):
                    path["rew"].append(rewards[a])
                    path["dur"].append(infos[a]["duration"])
                if terms[a] or truncs[a]:
                    paths.append(running.pop(a))
    return paths


def fill(model: PPO, paths: list[dict[str, list]]) -> None:
    """Put the paths into SB3's rollout buffer, in order, and compute its GAE."""
    buffer = model.rollout_buffer
    buffer.reset()
    for path in paths:
        for k in range(len(path["act"])):
            if buffer.full:
                # bootstrapped with the value of the observation the cut path continues from
                last = torch.tensor([path["value"][k]])
                buffer.compute_returns_and_advantage(last, np.array([False]))
                return
            buffer.add(path["obs"][k][None], np.array([[path["act"][k]]]),
                       np.array([path["rew"][k]]), np.array([k == 0]),
                       torch.tensor([path["value"][k]]), torch.tensor([path["logp"][k]]))
    buffer.compute_returns_and_advantage(torch.zeros(1), np.array([True]))


def policy_of(model: PPO):
    """The PPO policy as a ``repro`` policy (a batch of decisions -> actions), sampling."""
    def act(batch):
        with torch.no_grad():
            actions, _, _ = model.policy(torch.as_tensor(batch.obs, dtype=torch.float32))
        return actions.numpy().astype(np.int64)
    return act


def main(argv: list[str] | None = None) -> dict:
    """Train; returns each update's ADR of its training batch (average discounted return of its
    paths), the discount used and the test ADR with its standard error."""
    p = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()),
                                allow_abbrev=False)
    p.add_argument("--updates", type=int, default=20, help="PPO updates")
    p.add_argument("--n-steps", type=int, default=10_000, help="decisions per update")
    p.add_argument("--lam", type=float, default=1.0, help="the paper's lambda (wildfire: 1)")
    p.add_argument("--test-episodes", type=int, default=1000)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)

    torch.manual_seed(args.seed)
    cfg = WildfireConfig()
    env = parallel_env(cfg)
    env.reset(seed=args.seed)
    space = env.observation_space(env.possible_agents[0])
    model = PPO("MlpPolicy", Spaces(space, env.action_space(env.possible_agents[0])),
                n_steps=args.n_steps, batch_size=min(256, args.n_steps), n_epochs=5,
                policy_kwargs={"net_arch": [32]}, seed=args.seed, device="cpu", verbose=0)
    model.set_logger(configure(None, []))
    history = []
    for update in range(args.updates):
        paths = collect(env, model, args.n_steps)
        if update == 0:  # SB3's one discount per decision, from the mean duration
            m = float(np.mean(np.concatenate([q["dur"] for q in paths])))
            model.gamma = model.rollout_buffer.gamma = float(np.exp(-cfg.gamma * m))
            model.rollout_buffer.gae_lambda = float(np.exp(-cfg.gamma * (args.lam - 1.0) * m))
        history.append(float(np.mean([np.sum(np.exp(-cfg.gamma * (np.cumsum(q["dur"])
                                                                 - np.array(q["dur"])))
                                             * np.array(q["rew"])) for q in paths])))
        fill(model, paths)
        model.train()
        print(f"update {update + 1:3d}  paths {len(paths):5d}  training-batch ADR "
              f"{history[-1]:8.4f}")
    test = make_env(cfg).rollout(policy_of(model), args.test_episodes, args.seed + 1)
    mean, se = adr(test, cfg.gamma)
    print(f"test ADR over {args.test_episodes} episodes: {mean:.4f} +- {se:.4f} (s.e.)")
    return {"history": history, "gamma_d": model.gamma, "test_adr": mean, "test_se": se}


if __name__ == "__main__":
    torch.set_num_threads(1)
    main()
