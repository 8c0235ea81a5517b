"""The settings of one PS-TRPO + M-GAE run, each explained where it is defined."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

from repro.core.config import Validated, SCALES
from repro.core.errors import require
from repro.envs import env_package, train_defaults
from repro.learn.baseline import BASELINES
from repro.learn.m_gae import ESTIMATORS


@dataclass(frozen=True)
class TrainConfig(Validated):
    """Hyperparameters of one PS-TRPO + M-GAE run."""

    env: str = "toy"
    """Environment: a built-in one (toy, wildfire, bus) or an importable module
    (:func:`repro.envs.env_package`)."""
    epochs: int = 40
    """Policy updates; each samples a fresh batch."""
    batch_episodes: int = 50
    """Whole episodes simulated per epoch (the paper counts batches in episodes)."""
    lam: float = 1.0
    """M-GAE's lambda (the paper's lambda), any number >= 0. An advantage weights the residual of a
    decision made tau seconds later by e^{-gamma lam tau}, the paper's

        A^{M-GAE(gamma, lambda)}_k = sum_l exp(-gamma lam (T_{k+l} - T_k)) delta_{k+l}

    (docs/semantics.md section 5.3): lam scales the continuous-time discount rate, so values above
    1 are meaningful (later residuals weigh less than in the return; the bus trains with 2). It is
    not GAE's per-step lambda_d: with every duration 1 s, lambda_d = e^{-gamma (lam - 1)}. Named
    ``lam`` as ``lambda`` is Python's keyword; the name is serialised (config.json, run names such
    as ``lam2_batch540_seed0``, ``--lam``), so it stays."""
    advantage: str = "m-gae"
    """Advantage estimator (``repro.learn.m_gae.ESTIMATORS``; claim X1), m being the epoch's mean
    macro-action duration: "m-gae", the paper's M-GAE; "decision-gae", standard GAE with every
    macro-action one step, discount exp(-gamma m) and GAE lambda exp(-gamma (lam - 1) m), what a
    user of a standard library would do; "duration-gae", M-GAE's discount exp(-gamma dt) with that
    lambda constant per decision. Runs recorded before this setting existed used "m-gae"."""
    max_kl: float = 0.01
    """TRPO max step: bound on the mean KL between consecutive policies."""
    hidden: tuple[int, ...] = (32, 32)
    """Hidden layer sizes of the policy MLP (tanh)."""
    baseline: str = "linear"
    """Value baseline: "linear" (rllab's linear feature baseline, as the released implementation)
    or "mlp" (see repro.learn.baseline)."""
    baseline_hidden: tuple[int, ...] = (32, 32)
    """Hidden layer sizes of the "mlp" baseline (tanh)."""
    baseline_iters: int = 20
    """Full-batch L-BFGS iterations fitting the "mlp" baseline each epoch."""
    cg_iters: int = 10
    """Conjugate-gradient iterations for the natural-gradient direction (rllab: 10)."""
    cg_damping: float = 1e-5
    """Multiple of the identity added to the Fisher matrix (rllab's reg_coeff)."""
    backtrack_ratio: float = 0.8
    """Line-search shrink factor (rllab: 0.8)."""
    max_backtracks: int = 15
    """Line-search tries before the step is rejected (rllab: 15)."""
    fvp_subsample: float = 0.2
    """Fraction of the batch's decisions (drawn without replacement, afresh each epoch) on which
    the Fisher-vector products are computed; 1 = all (exact). rllab's ``subsample_factor``; OpenAI
    Baselines' TRPO uses every 5th decision. The Fisher matrix of a few thousand decisions is as
    good as that of the whole batch, and the products are most of a TRPO step's cost: on 25,000
    decisions (the paper's wildfire batch) 0.2 cut a step from 0.26 s to 0.07 s on a 2-core machine,
    with the autograd products that came before repro.learn.network."""
    normalize_obs: bool = True
    """Running mean/std observation normalisation (frozen within a batch)."""
    seed: int = 0
    """Root of every random stream of the run."""

    SCALES: ClassVar[dict[str, dict[str, Any]]] = {
        "smoke": dict(epochs=2, batch_episodes=8),
        "quick": {},
        "paper": {},
    }

    def validate(self) -> None:
        require(isinstance(self.env, str) and self.env != "", "--env", "an environment name",
                self.env)
        require(self.epochs >= 1, "--epochs", "an integer >= 1", self.epochs)
        require(self.batch_episodes >= 1, "--batch-episodes", "an integer >= 1",
                self.batch_episodes)
        require(self.lam >= 0 and math.isfinite(self.lam), "--lam", "a number >= 0", self.lam)
        require(self.advantage in ESTIMATORS, "--advantage", "one of " + ", ".join(ESTIMATORS),
                self.advantage)
        require(self.max_kl > 0 and math.isfinite(self.max_kl), "--max-kl", "a number > 0",
                self.max_kl)
        require(len(self.hidden) >= 1 and min(self.hidden) >= 1, "--hidden",
                "one or more positive layer sizes", list(self.hidden))
        require(self.baseline in BASELINES, "--baseline", "one of " + ", ".join(BASELINES),
                self.baseline)
        require(self.baseline_iters >= 1, "baseline_iters", "an integer >= 1", self.baseline_iters)
        require(self.cg_iters >= 1, "cg_iters", "an integer >= 1", self.cg_iters)
        require(self.cg_damping >= 0, "cg_damping", ">= 0", self.cg_damping)
        require(0 < self.backtrack_ratio < 1, "backtrack_ratio", "in (0, 1)", self.backtrack_ratio)
        require(0 < self.fvp_subsample <= 1, "--fvp-subsample", "in (0, 1]", self.fvp_subsample)
        require(self.max_backtracks >= 1, "max_backtracks", "an integer >= 1", self.max_backtracks)



def train_config(scale: str, env: str, **overrides: Any) -> TrainConfig:
    """The config at ``scale`` for ``env``: the environment's defaults (the paper's settings), then
    the scale, then explicit overrides (``None`` means not given)."""
    require(scale in SCALES, "--scale", "one of " + ", ".join(SCALES), scale)
    fields = {**train_defaults(env_package(env)), **TrainConfig.SCALES[scale], "env": env}
    fields.update({k: v for k, v in overrides.items() if v is not None})
    cfg = TrainConfig(**fields)
    return cfg


