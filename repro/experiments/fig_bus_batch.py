"""``fig-bus-batch``: the bus training curves over the batch sweep (see
repro.experiments.bus_sweeps)."""

from __future__ import annotations

import argparse

from repro.experiments import bus_sweeps


def add_arguments(p: argparse.ArgumentParser) -> None:
    bus_sweeps.add_arguments(p)


def run(args: argparse.Namespace) -> int:
    return bus_sweeps.run_named("batch", args)
