"""What M-GAE's rollout buffer adds to an SB3 update: CPU seconds of filling the buffer, of its
advantages and of ``PPO.train`` (5 epochs of minibatches of 250), with SB3's own buffer and GAE
and with :class:`repro.learn.sb3.MGAERolloutBuffer`, on the same batch of wildfire decisions
(medians of ``--repeats``).

    python examples/sb3_buffer_overhead.py --n-steps 10000 --repeats 5
"""

from __future__ import annotations

import argparse

import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.logger import configure

from repro.envs.wildfire import WildfireConfig
from repro.envs.wildfire.pettingzoo_env import parallel_env
from repro.learn.sb3 import MGAERolloutBuffer, Spaces, collect_paths, update_on

PARTS = ("fill", "advantages", "train")


def main(argv: list[str] | None = None) -> dict[str, dict[str, float]]:
    """Median CPU seconds of each part, per buffer ("sb3", "m-gae")."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n-steps", type=int, default=10_000, help="decisions in the buffer")
    p.add_argument("--repeats", type=int, default=5)
    args = p.parse_args(argv)
    cfg = WildfireConfig()
    envs = [parallel_env(cfg) for _ in range(8)]
    buffers = {"sb3": {}, "m-gae": dict(rollout_buffer_class=MGAERolloutBuffer,
                                        rollout_buffer_kwargs=dict(gamma_rate=cfg.gamma, lam=1.0))}
    models = {}
    for name, kwargs in buffers.items():
        models[name] = PPO("MlpPolicy", Spaces(envs[0]), n_steps=args.n_steps,
                           batch_size=min(250, args.n_steps), n_epochs=5,
                           policy_kwargs={"net_arch": [32]}, seed=0, device="cpu", **kwargs)
        models[name].set_logger(configure(None, []))
    paths = collect_paths(envs, models["sb3"], args.n_steps, seed=1)
    seconds = {name: {part: [] for part in PARTS} for name in models}
    for _ in range(args.repeats):
        for name, model in models.items():
            for part, dt in zip(PARTS, update_on(model, paths)):
                seconds[name][part].append(dt)
    medians = {name: {part: float(np.median(v)) for part, v in parts.items()}
               for name, parts in seconds.items()}
    for name, parts in medians.items():
        print(f"{name:6s} " + ", ".join(f"{part} {1000 * s:.1f} ms" for part, s in parts.items())
              + f"; all {1000 * sum(parts.values()):.0f} ms")
    extra = sum(medians["m-gae"][p] - medians["sb3"][p] for p in ("fill", "advantages"))
    print(f"the M-GAE buffer's filling and advantages minus SB3's: {1000 * extra:+.1f} ms, "
          f"{extra / sum(medians['sb3'].values()):+.1%} of SB3's whole update")
    return medians


if __name__ == "__main__":
    torch.set_num_threads(1)
    main()
