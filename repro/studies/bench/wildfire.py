"""Throughput of the fast wildfire engine against its SimPy reference, with the learner's policy in
the loop.

The cheap policy picks uniformly random actions (:class:`RandomPolicy`). The environment is the
default configuration, or that of the training run given by ``--checkpoint``. See
:mod:`repro.studies.bench.common` for what is timed and how.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from typing import Any, ClassVar

import pandas as pd

from repro.envs.wildfire import WildfireConfig, make_env, make_reference_env
from repro.envs.wildfire.policies import RandomPolicy
from repro.learn.trained_policy import trained_env_config
from repro.studies.bench import common as bench_common
from repro.studies.bench.common import BenchConfig
from repro.studies.kit.options import Command, Folders

VARIANTS = bench_common.VARIANTS


@dataclass(frozen=True)
class WildfireBenchConfig(BenchConfig):
    """Sizes of ``bench-wildfire`` (the fast engine runs the wildfire's training batch)."""

    SCALES: ClassVar[dict[str, dict[str, int]]] = bench_common.scales("wildfire")


def add_arguments(p: argparse.ArgumentParser) -> None:
    bench_common.add_arguments(p, WildfireBenchConfig)


def measure(cfg: WildfireBenchConfig, seed: int,
            trained: dict[str, Any] | None = None) -> pd.DataFrame:
    """``trained``: a loaded checkpoint of a wildfire run (``trainer.load_trained_run``)."""
    env_cfg = (WildfireConfig() if trained is None
               else trained_env_config(trained, WildfireConfig))
    return bench_common.measure(
        make_env(env_cfg), make_reference_env(env_cfg), "random",
        lambda env, rng: RandomPolicy(rng, n_observed=env_cfg.n_observed), cfg, seed, trained)


def configure(args: argparse.Namespace) -> Command:
    return bench_common.configure(args, WildfireBenchConfig)


def run(cmd: Command, folders: Folders) -> int:
    return bench_common.run(cmd, folders, "bench-wildfire", measure)
