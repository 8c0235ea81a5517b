"""What a training run folder's config.json holds (the TrainConfig, the environment's config and
its name), and the check that a folder is new or a run of the same settings."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any


from repro.core.config import saved_defaults, to_dict
from repro.learn.config import TrainConfig
from repro.runs.run_folder import check_same_run, config_dict


def run_config(cfg: TrainConfig, env_config: Any, env_name: str) -> dict[str, Any]:
    """What a run folder's config.json holds: the settings that determine the run."""
    return {"train": to_dict(cfg), "env": config_dict(env_config), "env_name": env_name}


def saved_run_defaults(env_config: Any, env_name: str) -> dict[str, Any]:
    """What a run folder's config.json held for a setting before the setting existed (None for
    environment configs that are not dataclasses)."""
    env = saved_defaults(type(env_config)) if dataclasses.is_dataclass(env_config) else None
    return {"train": saved_defaults(TrainConfig), "env": env, "env_name": env_name}


def saved_run_aliases(env_config: Any) -> dict[str, dict[str, str]]:
    """Old spellings of the settings a run folder's config.json may carry (the configs'
    ``ALIASES``: old key -> key), by section."""
    return {"train": TrainConfig.ALIASES, "env": getattr(type(env_config), "ALIASES", {})}


def check_run_folder(out: Path, cfg: TrainConfig, env_config: Any, env_name: str,
                     param: str = "--out") -> None:
    """Refuse (UsageError naming ``param`` and the first differing setting) a folder ``out`` that
    is neither new nor a run with these settings; only ``epochs`` may differ."""
    check_same_run(Path(out), run_config(cfg, env_config, env_name),
                   saved_run_defaults(env_config, env_name), param, saved_run_aliases(env_config))
