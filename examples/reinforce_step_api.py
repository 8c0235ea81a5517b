"""REINFORCE with a value baseline, written only against the step API and M-GAE.

One file that reads top to bottom: a small policy and value network (torch), ``n_envs`` episodes
stepped at once through ``repro.envs.make_vector_env``, every agent's macro-actions gathered into
its path, and an update on every batch of paths that ended with their episode. The advantages are
M-GAE's (``repro.learn.m_gae.m_gae_paths``): continuous-time discounting by each macro-action's
duration, as in the paper.

    python examples/reinforce_step_api.py --env wildfire --updates 20
    python examples/reinforce_step_api.py --env bus --n-envs 8 --updates 5
"""

from __future__ import annotations

import argparse

import numpy as np
import torch
from torch import nn

from repro.envs import make_vector_env
from repro.learn.m_gae import m_gae_paths


def mlp(n_in: int, n_out: int, hidden: int = 32) -> nn.Module:
    return nn.Sequential(nn.Linear(n_in, hidden), nn.Tanh(), nn.Linear(hidden, hidden), nn.Tanh(),
                         nn.Linear(hidden, n_out))


def main(argv: list[str] | None = None) -> list[float]:
    """Train; returns the mean undiscounted path return of every update's paths."""
    p = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()),
                                allow_abbrev=False)
    p.add_argument("--env", default="wildfire", choices=["wildfire", "bus"])
    p.add_argument("--n-envs", type=int, default=32, help="episodes stepped at once")
    p.add_argument("--paths", type=int, default=400, help="ended paths per update")
    p.add_argument("--updates", type=int, default=20)
    p.add_argument("--lr", type=float, default=3e-3)
    p.add_argument("--lam", type=float, default=0.95, help="M-GAE's lambda")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)

    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)  # the policy's sampling
    vec = make_vector_env(args.env, args.n_envs, args.seed)
    policy, value = mlp(vec.obs_dim, vec.n_actions), mlp(vec.obs_dim, 1)
    optimiser = torch.optim.Adam([*policy.parameters(), *value.parameters()], lr=args.lr)
    # observations vary in scale (metres, seconds, passengers): a fixed normaliser from the
    # first decisions keeps the networks' inputs near 1
    batch = vec.reset()
    scale = np.abs(batch.obs).mean(axis=0) + 1.0

    running: dict[tuple[int, int], dict[str, list]] = {}  # (episode, agent) -> its path so far
    ended: list[dict[str, list]] = []
    history = []
    while len(history) < args.updates:
        # act: sample every pending decision, remember it on its agent's path
        with torch.no_grad():
            logits = policy(torch.as_tensor(batch.obs / scale, dtype=torch.float32))
        probs = torch.softmax(logits, dim=1).numpy().astype(np.float64)
        actions = (probs.cumsum(axis=1) < rng.random((len(batch), 1))).sum(axis=1)
        actions = np.minimum(actions, vec.n_actions - 1)
        episode = vec.episode[batch.episode]
        for m in range(len(batch)):
            path = running.setdefault((episode[m], batch.agent[m]),
                                      {"obs": [], "act": [], "rew": [], "dur": []})
            path["obs"].append(batch.obs[m] / scale)
            path["act"].append(actions[m])
        batch, done = vec.step(actions)
        # the macro-actions that ended: their rewards and durations; a path is whole once its
        # episode ended
        for m in range(len(done)):
            key = (done.episode[m], done.agent[m])
            running[key]["rew"].append(done.reward[m])
            running[key]["dur"].append(done.duration[m])
            if done.done[m]:
                ended.append(running.pop(key))
        if len(ended) < args.paths:
            continue

        # update on the ended paths
        lengths = [len(q["act"]) for q in ended]
        path_start = np.concatenate([[0], np.cumsum(lengths)])
        obs = torch.as_tensor(np.concatenate([q["obs"] for q in ended]), dtype=torch.float32)
        act = torch.as_tensor(np.concatenate([q["act"] for q in ended]))
        rew = np.concatenate([q["rew"] for q in ended])
        dur = np.concatenate([q["dur"] for q in ended])
        v = value(obs).squeeze(1)
        adv, ret = m_gae_paths(rew, dur, v.detach().numpy(), path_start, vec.gamma, args.lam)
        adv = (adv - adv.mean()) / (adv.std() + 1e-8)
        logp = torch.log_softmax(policy(obs), dim=1).gather(1, act[:, None]).squeeze(1)
        loss = (-(logp * torch.as_tensor(adv, dtype=torch.float32)).mean()
                + 0.5 * ((v - torch.as_tensor(ret, dtype=torch.float32)) ** 2).mean())
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        history.append(float(np.mean(np.add.reduceat(rew, path_start[:-1]))))
        print(f"update {len(history):3d}  paths {len(ended):5d}  decisions {len(rew):7d}  "
              f"mean path reward {history[-1]:10.3f}")
        ended = []
    return history


if __name__ == "__main__":
    torch.set_num_threads(1)
    main()
