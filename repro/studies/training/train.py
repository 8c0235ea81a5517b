"""``train``: one PS-TRPO + M-GAE run into a run folder; the same command resumes it.

``--tensorboard DIR`` also logs each epoch's progress row (the columns of progress.csv but
``epoch``, which is the step) as TensorBoard scalars in DIR, with the optional ``tensorboard``
package (``pip install tensorboard``, the ``tensorboard`` extra). It does not change the run, so
it is an option of this command, not a training setting.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from repro.core.config import SCALES, canonical_keys
from repro.core.errors import UsageError, require
from repro.envs import BUILT_IN, env_package
from repro.learn.config import TrainConfig, add_learner_arguments, learner_overrides, train_config
from repro.learn.process import configure_process
from repro.learn.run_identity import saved_run_defaults
from repro.runs.files import check_writable_dir
from repro.studies.kit.environments import add_chosen_env_arguments

TENSORBOARD_INSTALL = "pip install tensorboard"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scale", default="quick",
                   help="one of " + ", ".join(SCALES) + " (default %(default)s; " + scale_text()
                        + ")")
    p.add_argument("--out", help="run folder (default runs/<env>/seed<seed>); rerun to resume")
    p.add_argument("--tensorboard", metavar="DIR",
                   help="also log each epoch's progress row as TensorBoard scalars in DIR "
                        f"(needs the tensorboard package: {TENSORBOARD_INSTALL})")
    add_learner_arguments(p)


def scale_text() -> str:
    """What each scale changes in a training run (TrainConfig.SCALES), as ``--help`` says it."""
    same = [scale for scale, fields in TrainConfig.SCALES.items() if not fields]
    other = [f"{scale}: " + ", ".join(f"{k} {v}" for k, v in fields.items())
             for scale, fields in TrainConfig.SCALES.items() if fields]
    return "; ".join([f"{' and '.join(same)} train with the settings below", *other])


def extend_arguments(p: argparse.ArgumentParser, argv: list[str]) -> None:
    """Add the chosen environment's own options (``--env`` decides which)."""
    add_chosen_env_arguments(p, argv)


def saved_settings(data: dict[str, Any]) -> dict[str, Any]:
    """A ``--config`` file's table; a run's config.json (sections ``train`` and ``env``, and
    ``env_name``) with old spellings of its keys renamed (the configs' ``ALIASES``) and completed
    with what the run held for the settings it lacks, which were added to the code after it
    started (:func:`repro.runs.run_folder.saved_run_defaults`)."""
    train, env, name = data.get("train"), data.get("env"), data.get("env_name")
    if not (isinstance(train, dict) and "env_name" in data):
        return data
    require(isinstance(name, str), "--config", "a run config naming its environment (env_name)",
            name)
    env_cfg = env_package(name).config_from_args(argparse.Namespace())
    saved = saved_run_defaults(env_cfg, name)
    train = {**saved["train"], **canonical_keys(TrainConfig, train)}
    if isinstance(env, dict) and saved["env"]:
        env = {**saved["env"], **canonical_keys(type(env_cfg), env)}
    return {**data, "train": train, "env": env}


@dataclass(frozen=True)
class TrainRun:
    """A training run as ``train``'s options give it."""

    train: TrainConfig
    """The learner's settings: the scale's, the named learner's, then the flags given."""
    env_config: Any
    """The environment's config (its package's), as its options give it."""
    out: Path
    """The run folder (``--out``; default runs/<env>/seed<seed>), checked writable."""
    tensorboard: str | None
    """A folder for TensorBoard scalars of each epoch's progress row (``--tensorboard``)."""


def configure(args: argparse.Namespace) -> TrainRun:
    """The run of :func:`add_arguments`'s options (and the chosen environment's)."""
    require(hasattr(args, "env"), "--env", "given: " + ", ".join(BUILT_IN)
            + ", or an importable module that provides the environment contract")
    cfg = train_config(args.scale, **learner_overrides(args))
    env_cfg = env_package(args.env).config_from_args(args)
    out = check_writable_dir(f"runs/{cfg.env}/seed{cfg.seed}" if args.out is None else args.out,
                             "--out")
    return TrainRun(train=cfg, env_config=env_cfg, out=out, tensorboard=args.tensorboard)


def run(training: TrainRun) -> int:
    cfg, env_cfg, out = training.train, training.env_config, training.out
    env = env_package(cfg.env).make_env(env_cfg)
    configure_process()
    from repro.learn.trainer import Trainer  # torch: imported once the options are checked

    board = None if training.tensorboard is None else TensorBoard(training.tensorboard)
    try:
        frame = Trainer(cfg, env, out, env_cfg).train(board)
    finally:
        if board is not None:
            board.close()
    last = frame.iloc[-1]
    extra = (f" (the run already had more than --epochs {cfg.epochs}: nothing trained)"
             if len(frame) > cfg.epochs else "")
    print(f"{cfg.env}: {len(frame)} epochs{extra}, average return {last.average_return:.6g}, "
          f"average discounted return {last.average_discounted_return:.6g} -> {out}")
    cut = frame.truncated_episodes.sum()
    if cut > 0:
        print(f"note: {cut:.0f} of {frame.batch_episodes.sum()} training episodes ended at the "
              f"decision limit (column truncated_episodes of progress.csv; --max-decisions)")
    return 0


class TensorBoard:
    """Progress rows as TensorBoard scalars in a folder: one tag per column, the epoch as step.
    The package is checked when this is made, before anything is written; the event file is made
    with the first row, so a run refused before its first epoch leaves nothing."""

    def __init__(self, folder: str):
        self.folder = check_writable_dir(folder, "--tensorboard")
        self.writer: Any = None
        try:
            from torch.utils.tensorboard import SummaryWriter
        except ImportError:
            raise UsageError("--tensorboard", "used with the tensorboard package installed "
                             f"({TENSORBOARD_INSTALL})", folder) from None
        self.summary_writer = SummaryWriter

    def __call__(self, row: dict[str, Any]) -> None:
        if self.writer is None:
            self.writer = self.summary_writer(str(self.folder))
        for column, value in row.items():
            if column != "epoch":
                self.writer.add_scalar(column, value, global_step=row["epoch"])
        self.writer.flush()

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()
