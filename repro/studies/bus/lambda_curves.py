"""``fig-bus-lambda``: the bus training curves over the lambda sweep (see
repro.studies.bus.sweeps)."""

from __future__ import annotations

import argparse

from repro.studies.kit.options import Command, Folders

from repro.studies.bus import sweeps as bus_sweeps

VARIANTS = bus_sweeps.VARIANTS


def add_arguments(p: argparse.ArgumentParser) -> None:
    bus_sweeps.add_arguments(p)


configure = bus_sweeps.configure


def run(cmd: Command, folders: Folders) -> int:
    return bus_sweeps.run_named("lambda", cmd, folders)
