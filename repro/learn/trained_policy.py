"""A trained policy from a run folder's checkpoint, ready to hand to an engine."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from repro.core.config import saved_defaults
from repro.core.errors import UsageError, require
from repro.runs.provenance import note_trained_under
from repro.runs.run_folder import (CHECKPOINT, CONFIG, KEPT, PROGRESS, load_checkpoint,
                                   progress_rows, recorded_kernels, state_problem)

if TYPE_CHECKING:
    from repro.learn.gru import GRUSampler
    from repro.learn.policy import Sampler

C = TypeVar("C")


def load_trained_run(path: str | Path, env_name: str,
                     param: str = "--checkpoint") -> dict[str, Any]:
    """The checkpoint at ``path`` of a training run on ``env_name``; a UsageError naming ``param``
    if it is none (missing, not a checkpoint, or a run on another environment). The kernels its
    run was trained under go into the command's sidecars
    (:func:`repro.runs.provenance.note_trained_under`) where the checkpoint is in a run folder."""
    allowed = f"the {CHECKPOINT} of a {env_name} training run"
    require(Path(path).is_file(), param, allowed, str(path))
    state = load_checkpoint(path, param, allowed)
    require(state.get("run_config", {}).get("env_name") == env_name, param, allowed, str(path))
    folder = Path(path).parent
    folder = folder.parent if folder.name == KEPT else folder  # a kept policy's run folder
    if (folder / PROGRESS).is_file():
        rows = progress_rows(folder)
        require(state["epoch"] <= rows, param, f"{allowed} whose epoch ({state['epoch']}) its "
                f"run's {PROGRESS} holds (it holds {rows} epochs)", str(path))
    if (folder / CONFIG).is_file():
        note_trained_under(recorded_kernels(folder, param))
    return state


def policy_from_checkpoint(path: str | Path,
                           rng: np.random.Generator) -> Sampler | GRUSampler:
    """The trained policy of a run folder's checkpoint, ready to hand to an engine (a UsageError
    if the file is not a whole checkpoint of this suite)."""
    return policy_from_state(load_checkpoint(path, "checkpoint"), rng)


def policy_from_state(state: dict[str, Any], rng: np.random.Generator) -> Sampler | GRUSampler:
    """The trained policy of a loaded checkpoint (:func:`load_checkpoint`): an MLP's
    :class:`Sampler` or a gru's :class:`GRUSampler` (which keeps each agent's state: one per
    rollout at a time). Both sample with ``rng`` when called and have ``greedy``."""
    # torch: imported where a policy is made, so that a command's options are checked without it
    from repro.learn.gru import GRUSampler, gru_policy
    from repro.learn.policy import CategoricalPolicy, ObsNormalizer, Sampler

    cfg = state["run_config"]["train"]
    obs_dim = len(state["normalizer"]["mean"])
    n_actions = state["policy"][next(reversed(state["policy"]))].shape[0]
    gru = cfg.get("policy", "mlp") == "gru"
    policy = (gru_policy(obs_dim, n_actions, cfg) if gru
              else CategoricalPolicy(obs_dim, n_actions, cfg["hidden"]))
    policy.load_state_dict(state["policy"])
    normalizer = ObsNormalizer(obs_dim)
    normalizer.load_state_dict(state["normalizer"])
    return (GRUSampler if gru else Sampler)(policy, normalizer, rng)


def trained_env_config(state: dict[str, Any], config: type[C],
                       param: str = "--checkpoint") -> C:
    """The environment settings of a checkpoint's run as ``config`` (settings newer than the run
    keep their defaults, as when it resumes); a UsageError naming ``param`` if they are not
    settings of ``config``."""
    env = state["run_config"].get("env") or {}
    try:
        saved = {**saved_defaults(config), **env}
        return config(**{k: tuple(v) if isinstance(v, list) else v for k, v in saved.items()})
    except (TypeError, ValueError):  # unknown or bad settings (UsageError is a ValueError)
        raise UsageError(param, f"the {CHECKPOINT} of a training run whose environment settings "
                         f"are those of {config.__name__}", str(env)[:80]) from None


def check_fits(state: dict[str, Any], env: Any, param: str, where: Any) -> None:
    """Refuse (UsageError naming ``param``) a checkpoint whose policy does not take ``env``'s
    observations or give its actions."""
    problem = state_problem(state, env.obs_dim, env.n_actions)
    require(problem is None, param, f"the {CHECKPOINT} of a run on this environment ({problem})",
            None if where is None else str(where))
