"""A trained policy from a run folder's checkpoint, ready to hand to an engine."""

from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from repro.core.errors import require
from repro.learn.policy import CategoricalPolicy, ObsNormalizer, Sampler
from repro.learn.run_folder import CHECKPOINT, load_checkpoint
from repro.core.config import saved_defaults

C = TypeVar("C")


def load_trained_run(path: str | Path, env_name: str,
                     param: str = "--checkpoint") -> dict[str, Any]:
    """The checkpoint at ``path`` of a training run on ``env_name``; a UsageError naming ``param``
    if it is none (missing, not a checkpoint, or a run on another environment)."""
    allowed = f"the {CHECKPOINT} of a {env_name} training run"
    require(Path(path).is_file(), param, allowed, str(path))
    state = load_checkpoint(path, param, allowed)
    require(state.get("run_config", {}).get("env_name") == env_name, param, allowed, str(path))
    return state


def policy_from_checkpoint(path: str | Path, rng: np.random.Generator) -> Sampler:
    """The trained policy of a run folder's checkpoint, ready to hand to an engine."""
    return policy_from_state(load_checkpoint(path), rng)


def policy_from_state(state: dict[str, Any], rng: np.random.Generator) -> Sampler:
    """The trained policy of a loaded checkpoint (:func:`load_checkpoint`)."""
    cfg = state["run_config"]["train"]
    obs_dim = len(state["normalizer"]["mean"])
    n_actions = state["policy"][next(reversed(state["policy"]))].shape[0]
    policy = CategoricalPolicy(obs_dim, n_actions, cfg["hidden"])
    policy.load_state_dict(state["policy"])
    normalizer = ObsNormalizer(obs_dim)
    normalizer.load_state_dict(state["normalizer"])
    return Sampler(policy, normalizer, rng)


def trained_env_config(state: dict[str, Any], config: type[C]) -> C:
    """The environment settings of a checkpoint's run as ``config`` (settings newer than the run
    keep their defaults, as when it resumes)."""
    saved = {**saved_defaults(config), **(state["run_config"]["env"] or {})}
    return config(**{k: tuple(v) if isinstance(v, list) else v for k, v in saved.items()})
