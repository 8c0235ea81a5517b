"""PS-TRPO with M-GAE (docs/semantics.md section 5): a categorical MLP shared by all agents,
trained by TRPO on advantages that discount by each macro-action's duration.

The names below are imported from their modules when first used (``from repro.learn import
Trainer`` works as ever): a module that needs only the learner's settings
(:mod:`repro.learn.config`) does not import torch, so a command's options are read and checked
before the heavy imports."""

from __future__ import annotations

import importlib
from typing import Any

# M-GAE needs only numpy and numba; imported now, so that the function ``m_gae`` and not its
# submodule of the same name is what ``from repro.learn import m_gae`` gives
from repro.learn.m_gae import m_gae, m_gae_paths, macro_gae

_HOME = {
    "LinearFeatureBaseline": "baseline", "MLPBaseline": "baseline",
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

__all__ = ["m_gae", "m_gae_paths", "macro_gae", *_HOME]


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_HOME[name]}"), name)
