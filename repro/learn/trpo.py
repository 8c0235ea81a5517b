"""One TRPO policy update, split into small functions (the layout follows sb3-contrib's TRPO; the
constants follow rllab's ConjugateGradientOptimizer, which produced the paper's results).

maximise  L(theta) = mean_k  pi_theta(a_k|o_k) / pi_old(a_k|o_k) * A_k
s.t.      mean_k KL(pi_old(.|o_k) || pi_theta(.|o_k)) <= max_kl

The natural-gradient direction s solves F s = grad L by conjugate gradient, F being the Hessian of
the mean KL at theta_old (the Fisher matrix, applied as a product, never formed). The step
sqrt(2 max_kl / s'Fs) s would meet the KL bound exactly under the quadratic model; a backtracking line
search shrinks it until the true KL is within the bound AND the surrogate improved, and otherwise
leaves the parameters where they were.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import torch
from torch import nn
from torch.nn.utils import parameters_to_vector, vector_to_parameters


@dataclass(frozen=True)
class TRPOStats:
    """Diagnostics of one update."""

    kl: float
    """Mean KL(old || new) after the update (0 when the step was rejected)."""
    entropy: float
    """Mean entropy of the old policy over the batch's decisions."""
    surrogate_before: float
    surrogate_after: float
    backtracks: int
    """Line-search shrinks before acceptance (max_backtracks when rejected)."""
    accepted: bool


def normalize(adv: np.ndarray) -> np.ndarray:
    """Advantages centred and scaled to unit standard deviation over the batch."""
    return (adv - adv.mean()) / (adv.std() + 1e-8)


def conjugate_gradient(matvec: Callable[[torch.Tensor], torch.Tensor], b: torch.Tensor,
                       iters: int, residual_tol: float = 1e-10) -> torch.Tensor:
    """Approximately solve A x = b for symmetric positive-definite A given only x -> A x."""
    x = torch.zeros_like(b)
    r = b.clone()
    p = b.clone()
    rr = r @ r
    for _ in range(iters):
        if rr < residual_tol:
            break
        ap = matvec(p)
        alpha = rr / (p @ ap)
        x += alpha * p
        r -= alpha * ap
        rr_new = r @ r
        p = r + (rr_new / rr) * p
        rr = rr_new
    return x


def mean_kl(logp_old: torch.Tensor, logp_new: torch.Tensor) -> torch.Tensor:
    """mean over rows of KL(old || new), both given as (N, n_actions) log-probabilities."""
    return (logp_old.exp() * (logp_old - logp_new)).sum(dim=1).mean()


def fisher_vector_product(policy: nn.Module, obs: torch.Tensor,
                          damping: float) -> Callable[[torch.Tensor], torch.Tensor]:
    """v -> (F + damping I) v, F the Hessian of the mean KL at the current parameters.

    For a categorical policy that Hessian is exactly J' diag(p) J / N, J the Jacobian of the
    log-probabilities with respect to the parameters, so each product is J v (by differentiating
    J' w in w), a weighting by p, and J' u: two backward passes, no forward pass and no second
    derivative of the network beyond what J v needs.
    """
    params = [p for p in policy.parameters()]
    logp = policy(obs)
    probs = logp.detach().exp()
    w = torch.zeros_like(logp, requires_grad=True)
    jt_w = torch.autograd.grad(logp, params, w, create_graph=True)
    n = len(obs)

    def fvp(v: torch.Tensor) -> torch.Tensor:
        pieces, i = [], 0
        for p in params:
            pieces.append(v[i:i + p.numel()].view_as(p))
            i += p.numel()
        jv = torch.autograd.grad(jt_w, w, pieces, retain_graph=True)[0]
        jt_u = torch.autograd.grad(logp, params, probs * jv / n, retain_graph=True)
        return torch.cat([g.reshape(-1) for g in jt_u]) + damping * v

    return fvp


def line_search(policy: nn.Module, evaluate: Callable[[], tuple[float, float]],
                full_step: torch.Tensor, surrogate_before: float, max_kl: float,
                backtrack_ratio: float, max_backtracks: int) -> tuple[bool, int, float, float]:
    """Try theta_old + ratio^i full_step for i = 0, 1, ...; keep the first with KL <= max_kl and a
    higher surrogate. ``evaluate()`` returns (surrogate, KL) at the policy's current parameters.
    Returns (accepted, backtracks, surrogate, KL); on rejection the old parameters are restored."""
    old = parameters_to_vector(policy.parameters()).detach().clone()
    for i in range(max_backtracks):
        vector_to_parameters(old + backtrack_ratio**i * full_step, policy.parameters())
        surr, kl = evaluate()
        if np.isfinite(surr) and np.isfinite(kl) and kl <= max_kl and surr > surrogate_before:
            return True, i, surr, kl
    vector_to_parameters(old, policy.parameters())
    return False, max_backtracks, surrogate_before, 0.0


def trpo_step(policy: nn.Module, obs: torch.Tensor, actions: torch.Tensor, adv: torch.Tensor, *,
              max_kl: float, cg_iters: int, cg_damping: float, backtrack_ratio: float,
              max_backtracks: int, fvp_rows: torch.Tensor | None = None) -> TRPOStats:
    """One constrained update of ``policy`` (log-probabilities of normalised observations) on a
    batch; ``adv`` should already be normalised. ``fvp_rows`` (indices into the batch) restricts the
    Fisher-vector products, and so the step size, to those rows (rllab's ``subsample_factor``); the
    gradient and the line search always use the whole batch."""
    logp = policy(obs)
    logp_old = logp.detach()
    logp_old_a = logp_old.gather(1, actions[:, None])[:, 0]
    entropy = float(-(logp_old.exp() * logp_old).sum(dim=1).mean())

    def surrogate(logp: torch.Tensor) -> torch.Tensor:
        return (torch.exp(logp.gather(1, actions[:, None])[:, 0] - logp_old_a) * adv).mean()

    params = list(policy.parameters())
    surr = surrogate(logp)
    grad = torch.cat([g.reshape(-1) for g in torch.autograd.grad(surr, params)])
    surr0 = float(surr.detach())
    fvp = fisher_vector_product(policy, obs if fvp_rows is None else obs[fvp_rows], cg_damping)
    direction = conjugate_gradient(fvp, grad, cg_iters)
    shs = float(direction @ fvp(direction))
    if not shs > 0.0:  # zero gradient (e.g. all advantages equal): nothing to do
        return TRPOStats(0.0, entropy, surr0, surr0, 0, False)
    full_step = np.sqrt(2.0 * max_kl / shs) * direction

    def evaluate() -> tuple[float, float]:
        with torch.no_grad():
            logp = policy(obs)
            return float(surrogate(logp)), float(mean_kl(logp_old, logp))

    accepted, backtracks, surr1, kl = line_search(policy, evaluate, full_step, surr0, max_kl,
                                                  backtrack_ratio, max_backtracks)
    return TRPOStats(kl, entropy, surr0, surr1, backtracks, accepted)
