"""Speed of the fast bus engine against its SimPy reference, with the learner's policy in the loop.

The cheap policy is No Holding. The engine is deterministic: the seed only drives the policy. See
:mod:`repro.studies.bench.common` for what is timed and how.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from typing import Any, ClassVar

import pandas as pd

from repro.envs.bus import BusConfig, make_env, make_reference_env
from repro.envs.bus.policies import no_holding
from repro.learn.trained_policy import trained_env_config
from repro.studies.bench import common as bench_common
from repro.studies.bench.common import BenchConfig
from repro.studies.kit.options import Command, Folders

VARIANTS = bench_common.VARIANTS


@dataclass(frozen=True)
class BusBenchConfig(BenchConfig):
    """Sizes of ``bench-bus`` (the fast engine runs the bus's training batch)."""

    SCALES: ClassVar[dict[str, dict[str, int]]] = bench_common.scales("bus")


def add_arguments(p: argparse.ArgumentParser) -> None:
    bench_common.add_arguments(p, BusBenchConfig)


def measure(cfg: BusBenchConfig, seed: int, trained: dict[str, Any] | None = None) -> pd.DataFrame:
    """``trained``: a loaded checkpoint of a bus run (``trainer.load_trained_run``)."""
    env_cfg = (BusConfig() if trained is None
               else trained_env_config(trained, BusConfig))
    return bench_common.measure(make_env(env_cfg), make_reference_env(env_cfg), "nohold",
                                lambda env, rng: no_holding, cfg, seed, trained)


def configure(args: argparse.Namespace) -> Command:
    return bench_common.configure(args, BusBenchConfig)


def run(cmd: Command, folders: Folders) -> int:
    return bench_common.run(cmd, folders, "bench-bus", measure)
