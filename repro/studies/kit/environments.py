"""The options of the environment a command's ``--env`` chooses, which the commands that train
take (``train``, ``bench-learn``)."""

from __future__ import annotations

import argparse

from repro.envs import env_package


def add_chosen_env_arguments(p: argparse.ArgumentParser, argv: list[str]) -> None:
    """Add the chosen environment's own options (``--env`` in ``argv`` decides which)."""
    pre = argparse.ArgumentParser(add_help=False, allow_abbrev=False)
    pre.add_argument("--env")
    name = pre.parse_known_args(argv)[0].env
    if name is not None:
        env_package(name).add_env_arguments(p)
