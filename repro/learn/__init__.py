"""PS-TRPO with M-GAE (docs/semantics.md section 5): a categorical MLP shared by all agents,
trained by TRPO on advantages that discount by each macro-action's duration."""

from repro.learn.baseline import LinearFeatureBaseline, MLPBaseline
from repro.learn.m_gae import m_gae, m_gae_paths, macro_gae
from repro.learn.network import TanhMLP
from repro.learn.policy import CategoricalPolicy, ObsNormalizer, Sampler
from repro.learn.config import TrainConfig, train_config
from repro.learn.process import configure_process
from repro.learn.trained_policy import policy_from_checkpoint
from repro.learn.trainer import Trainer
from repro.learn.trpo import (TRPOStats, conjugate_gradient, fisher_vector_product, line_search,
                              trpo_step)

__all__ = ["m_gae", "m_gae_paths", "macro_gae", "TanhMLP", "CategoricalPolicy", "ObsNormalizer",
           "Sampler",
           "LinearFeatureBaseline", "MLPBaseline", "TrainConfig", "Trainer", "train_config",
           "configure_process", "policy_from_checkpoint", "TRPOStats", "conjugate_gradient",
           "fisher_vector_product", "line_search", "trpo_step"]
