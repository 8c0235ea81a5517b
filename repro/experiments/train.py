"""``train``: one PS-TRPO + M-GAE run into a run folder; the same command resumes it."""

from __future__ import annotations

import argparse
from typing import Any

from repro.core.config import SCALES, canonical_keys
from repro.core.errors import require
from repro.core.io import check_writable_dir
from repro.core.rollout import BatchEnv
from repro.envs import BUILT_IN, env_package
from repro.learn.config import (TrainConfig, add_learner_arguments, learner_overrides,
                                train_config)
from repro.learn.trainer import Trainer, saved_run_defaults


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scale", default="quick", help="one of " + ", ".join(SCALES))
    p.add_argument("--out", help="run folder (default runs/<env>/seed<seed>); rerun to resume")
    add_learner_arguments(p)


def extend_arguments(p: argparse.ArgumentParser, argv: list[str]) -> None:
    """Add the chosen environment's own options (``--env`` decides which)."""
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--env")
    name = pre.parse_known_args(argv)[0].env
    if name is not None:
        env_package(name).add_env_arguments(p)


def saved_settings(data: dict[str, Any]) -> dict[str, Any]:
    """A ``--config`` file's table; a run's config.json (sections ``train`` and ``env``, and
    ``env_name``) with old spellings of its keys renamed (the configs' ``ALIASES``) and completed
    with what the run held for the settings it lacks, which were added to the code after it
    started (:func:`repro.learn.trainer.saved_run_defaults`)."""
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


def make_from_args(args: argparse.Namespace, **overrides: Any) -> tuple[TrainConfig, BatchEnv, Any]:
    """Train config, environment and environment config from parsed ``train``-style options."""
    require(hasattr(args, "env"), "--env", "given: " + ", ".join(BUILT_IN)
            + ", or an importable module that provides the environment contract")
    pkg = env_package(args.env)
    cfg = train_config(args.scale, **{**learner_overrides(args), **overrides})
    env_cfg = pkg.config_from_args(args)
    return cfg, pkg.make_env(env_cfg), env_cfg


def run(args: argparse.Namespace) -> int:
    cfg, env, env_cfg = make_from_args(args)
    out = check_writable_dir(f"runs/{cfg.env}/seed{cfg.seed}" if args.out is None else args.out,
                             "--out")
    frame = Trainer(cfg, env, out, env_cfg).train()
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
