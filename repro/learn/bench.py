"""``bench-learn``: seconds per training epoch split into simulation and update (TRPO + baseline),
at about 1,000 episodes per epoch, so that the update is checked not to be the bottleneck."""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import dataclass
from typing import Any, ClassVar

from repro.cli import add_common
from repro.core.config import for_scale
from repro.core.errors import require
from repro.core.io import check_writable_dir, provenance, write_result
from repro.learn import trainer


@dataclass(frozen=True)
class BenchConfig:
    """Size of the timing run."""

    episodes: int = 1000
    """Episodes per epoch."""
    epochs: int = 3
    """Epochs timed (the first includes numba compilation of cached kernels if not yet cached)."""

    SCALES: ClassVar[dict[str, dict[str, Any]]] = {
        "smoke": dict(episodes=100, epochs=1),
        "quick": {},
        "paper": dict(epochs=5),
    }

    def validate(self) -> None:
        require(self.episodes >= 1, "--episodes", "an integer >= 1", self.episodes)
        require(self.epochs >= 1, "--epochs", "an integer >= 1", self.epochs)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p)
    p.add_argument("--env", default="toy", help="environment: " + ", ".join(trainer.ENVS))
    p.add_argument("--episodes", type=int, help="episodes per epoch (1000)")
    p.add_argument("--epochs", type=int, help="epochs timed (3)")


def extend_arguments(p: argparse.ArgumentParser, argv: list[str]) -> None:
    trainer.extend_arguments(p, argv if "--env" in argv else [*argv, "--env", "toy"])


def run(args: argparse.Namespace) -> int:
    cfg = for_scale(BenchConfig, args.scale, episodes=args.episodes, epochs=args.epochs)
    cfg.validate()
    pkg = trainer.env_package(args.env)
    train_cfg = trainer.train_config("quick", args.env, seed=args.seed, epochs=cfg.epochs,
                                     batch_episodes=cfg.episodes)
    env_cfg = pkg.config_from_args(args)
    results = check_writable_dir(args.results_dir, "--results-dir")
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:  # checkpoints are written, as in a real run
        frame = trainer.Trainer(train_cfg, pkg.make_env(env_cfg), out, env_cfg).train()
    wall = time.perf_counter() - t0
    table = frame[["epoch", "batch_episodes", "decisions", *trainer.TIMING_COLUMNS]].copy()
    table.insert(0, "env", args.env)
    table["update_share"] = table.seconds_update / (table.seconds_sim + table.seconds_update)
    prov = provenance({"bench": cfg, "train": train_cfg, "env": trainer.config_dict(env_cfg)},
                      command="bench-learn", scale=args.scale, seed=args.seed, wall_seconds=wall)
    write_result(results / "bench_learn.csv", table, prov)
    print(table.to_string(index=False))
    return 0
