"""PS-TRPO with M-GAE (docs/semantics.md section 5): a categorical MLP shared by all agents,
trained by TRPO on advantages that discount by each macro-action's duration.

The names below are imported from their modules when first used (``from repro.learn import
Trainer`` works as ever): a module that needs only the learner's settings
(:mod:`repro.learn.config`) does not import torch, so a command's options are read and checked
before the heavy imports."""

from __future__ import annotations

import importlib
from typing import Any

_HOME = {
    "LinearFeatureBaseline": "baseline", "MLPBaseline": "baseline",
    "m_gae": "m_gae", "m_gae_paths": "m_gae", "macro_gae": "m_gae",
    "TanhMLP": "network",
    "CategoricalPolicy": "policy", "ObsNormalizer": "policy", "Sampler": "policy",
    "TrainConfig": "config", "train_config": "config",
    "configure_process": "process",
    "policy_from_checkpoint": "trained_policy",
    "Trainer": "trainer",
    "TRPOStats": "trpo", "conjugate_gradient": "trpo", "fisher_vector_product": "trpo",
    "line_search": "trpo", "trpo_step": "trpo",
}
"""Each name this package exports -> its module."""

__all__ = list(_HOME)


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_HOME[name]}"), name)
