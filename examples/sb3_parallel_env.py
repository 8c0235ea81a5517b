"""Stable-Baselines3's PPO (or A2C) trains one shared policy on the wildfire through the
PettingZoo ParallelEnv (``repro.envs.wildfire.pettingzoo_env.parallel_env``), with M-GAE or with
SB3's own GAE.

What it does (:mod:`repro.learn.sb3`, docs/own-learner.md): each update plays whole episodes of
``--envs`` ParallelEnvs side by side, sampling every deciding UAV's action from SB3's policy
(``infos[uav]["decides"]``: a UAV whose macro-action runs on is not asked), keeps every UAV's
decisions of an episode as one path, with the rewards the env hands out (each macro-action's,
discounted to its start) and the durations of its ``infos``, lays the paths into the model's
rollout buffer and runs SB3's own update (``model.train()``: its clipped objective, optimiser and
minibatches).

- ``--estimator m-gae`` (the default): the buffer is
  :class:`repro.learn.sb3.MGAERolloutBuffer`, which stores each decision's duration and computes
  the paper's M-GAE: discount exp(-gamma dt_k) per macro-action, trace exp(-gamma lam dt_k).
- ``--estimator gae``: SB3's own buffer and GAE, one step per decision, with gamma_d =
  exp(-gamma m) and lambda_d = exp(-gamma (lam - 1) m), m the first batch's mean macro-action
  duration (the ``decision-gae`` estimator of :mod:`repro.learn.m_gae`, claim X1).

ADR is measured on test episodes of the fast engine with the policy sampling, as ``repro``'s
evaluation does. ``python -m repro beyond-sb3`` compares both with PS-TRPO.

    python examples/sb3_parallel_env.py --updates 20 --n-steps 10000
"""

from __future__ import annotations

import argparse

import numpy as np
import stable_baselines3
import torch
from stable_baselines3.common.logger import configure

from repro.envs.wildfire import WildfireConfig, make_env
from repro.envs.wildfire.pettingzoo_env import parallel_env
from repro.learn.sb3 import MGAERolloutBuffer, Spaces, as_policy, path_adr, train_update
from repro.studies.wildfire.study import adr


def main(argv: list[str] | None = None) -> dict:
    """Train; returns each update's ADR of its training batch (average discounted return of its
    paths), SB3's discount per decision (``gae``; 0 with M-GAE, which discounts by duration) and
    the test ADR with its standard error."""
    p = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()),
                                allow_abbrev=False)
    p.add_argument("--algorithm", choices=("PPO", "A2C"), default="PPO")
    p.add_argument("--estimator", choices=("m-gae", "gae"), default="m-gae")
    p.add_argument("--updates", type=int, default=20, help="policy updates")
    p.add_argument("--n-steps", type=int, default=10_000, help="decisions per update")
    p.add_argument("--envs", type=int, default=8,
                   help="ParallelEnvs played side by side (one policy call for all)")
    p.add_argument("--lam", type=float, default=1.0, help="the paper's lambda (wildfire: 1)")
    p.add_argument("--test-episodes", type=int, default=1000)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)

    cfg = WildfireConfig()
    envs = [parallel_env(cfg) for _ in range(args.envs)]
    buffer = (dict(rollout_buffer_class=MGAERolloutBuffer,
                   rollout_buffer_kwargs=dict(gamma_rate=cfg.gamma, lam=args.lam))
              if args.estimator == "m-gae" else {})
    minibatches = dict(batch_size=min(250, args.n_steps), n_epochs=5) if args.algorithm == "PPO" \
        else {}
    model = getattr(stable_baselines3, args.algorithm)(
        "MlpPolicy", Spaces(envs[0]), n_steps=args.n_steps, policy_kwargs={"net_arch": [32]},
        seed=args.seed, device="cpu", **minibatches, **buffer)
    model.set_logger(configure(None, []))

    def decision_discount(paths):  # SB3's one discount per decision, from the mean duration
        m = float(np.mean(np.concatenate([q["dur"] for q in paths])))
        model.gamma = model.rollout_buffer.gamma = float(np.exp(-cfg.gamma * m))
        model.rollout_buffer.gae_lambda = float(np.exp(-cfg.gamma * (args.lam - 1.0) * m))

    history = []
    for update in range(args.updates):
        first = update == 0 and args.estimator == "gae"
        paths, _ = train_update(envs, model, seed=args.seed + update,
                                on_batch=decision_discount if first else None)
        history.append(path_adr(paths, cfg.gamma))
        print(f"update {update + 1:3d}  paths {len(paths):5d}  training-batch ADR "
              f"{history[-1]:8.4f}")
    torch.manual_seed(args.seed + 1)  # the test's action draws
    test = make_env(cfg).rollout(as_policy(model), args.test_episodes, args.seed + 1)
    mean, se = adr(test, cfg.gamma)
    print(f"test ADR over {args.test_episodes} episodes: {mean:.4f} +- {se:.4f} (s.e.)")
    return {"history": history, "gamma_d": model.gamma if args.estimator == "gae" else 0.0,
            "test_adr": mean, "test_se": se}


if __name__ == "__main__":
    torch.set_num_threads(1)
    main()
