"""One TRPO policy update, split into small functions (the layout follows sb3-contrib's TRPO; the
constants follow rllab's ConjugateGradientOptimizer, which produced the paper's results).

maximise  L(theta) = mean_k  pi_theta(a_k|o_k) / pi_old(a_k|o_k) * A_k
s.t.      mean_k KL(pi_old(.|o_k) || pi_theta(.|o_k)) <= max_kl

The natural-gradient direction s solves F s = grad L by conjugate gradient, F being the Hessian of
the mean KL at theta_old (the Fisher matrix, applied as a product, never formed). The step
sqrt(2 max_kl / s'Fs) s would meet the KL bound exactly under the quadratic model; a backtracking
line search shrinks it until the true KL is within the bound AND the surrogate improved, and
otherwise leaves the parameters where they were.

The products with the network's Jacobian are written out (:mod:`repro.learn.network`), not taken by
autograd. Batches: observations (N, obs_dim); log-probabilities action-major, (n_actions, N). The
network computes in its own dtype (float32 in training); conjugate gradient runs in float64.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import torch

from repro.learn.network import Forward, TanhMLP, log_softmax


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


def mean_kl(logp_old: torch.Tensor, logp_new: torch.Tensor) -> float:
    """Mean over decisions of KL(old || new), both (n_actions, N) log-probabilities."""
    return float((logp_old.exp() * (logp_old - logp_new)).sum(dim=0).mean(dtype=torch.float64))


def surrogate_gradient(net: TanhMLP, fwd: Forward, probs: torch.Tensor, actions: torch.Tensor,
                       adv: torch.Tensor) -> torch.Tensor:
    """grad L at theta_old = mean_k A_k grad log pi(a_k|o_k). The derivative of log pi(a|o) with
    respect to the logits is onehot(a) - pi(.|o), so this is one backward pass of those columns."""
    n = len(actions)
    g = probs * (-adv / n)
    g[actions, torch.arange(n)] += adv / n
    return net.vjp(fwd, g).double()


def fisher_vector_product(net: TanhMLP, fwd: Forward,
                          damping: float) -> Callable[[torch.Tensor], torch.Tensor]:
    """v -> (F + damping I) v, F the Hessian of the mean KL at the parameters of ``fwd``.

    For a categorical policy that Hessian is J' M J / N, J the Jacobian of the logits with respect
    to the parameters and M = diag(p) - p p' the Hessian of the KL in the logits, per decision. So a
    product is a forward-mode pass (J v), a weighting, and a backward pass (J' u), no second
    derivatives of the network.
    """
    probs = log_softmax(fwd.logits).exp()
    n = probs.shape[1]

    def fvp(v: torch.Tensor) -> torch.Tensor:
        jv = net.jvp(fwd, v)
        u = probs * (jv - (probs * jv).sum(dim=0))
        return net.vjp(fwd, u.div_(n)).double() + damping * v

    return fvp


def surrogate_and_kl(net: TanhMLP, obs: torch.Tensor, actions: torch.Tensor, adv: torch.Tensor,
                     logp_old: torch.Tensor) -> tuple[float, float]:
    """(L, mean KL(old || current)) at the network's current parameters: one forward pass over
    the batch, which is what each line-search trial costs."""
    logp = log_softmax(net.forward(obs).logits)
    taken = (actions, torch.arange(len(actions)))
    ratio = (logp[taken] - logp_old[taken]).exp_()
    return float((ratio * adv).mean(dtype=torch.float64)), mean_kl(logp_old, logp)


def line_search(net: TanhMLP, evaluate: Callable[[], tuple[float, float]],
                full_step: torch.Tensor, surrogate_before: float, max_kl: float,
                backtrack_ratio: float, max_backtracks: int) -> tuple[bool, int, float, float]:
    """Try theta_old + ratio^i full_step for i = 0, 1, ...; keep the first with KL <= max_kl and a
    higher surrogate. ``evaluate()`` returns (surrogate, KL) at the network's current parameters.
    Returns (accepted, backtracks, surrogate, KL); on rejection the old parameters are restored."""
    old = net.get_flat()
    for i in range(max_backtracks):
        net.set_flat(old + backtrack_ratio**i * full_step)
        surr, kl = evaluate()
        if np.isfinite(surr) and np.isfinite(kl) and kl <= max_kl and surr > surrogate_before:
            return True, i, surr, kl
    net.set_flat(old)
    return False, max_backtracks, surrogate_before, 0.0


def trpo_step(net: TanhMLP, obs: torch.Tensor, actions: torch.Tensor, adv: torch.Tensor, *,
              max_kl: float, cg_iters: int, cg_damping: float, backtrack_ratio: float,
              max_backtracks: int, fvp_rows: torch.Tensor | None = None) -> TRPOStats:
    """One constrained update of the logit network ``net`` on a batch: normalised observations
    ``obs`` (N, obs_dim) in the network's dtype, ``actions`` (N,), ``adv`` (N,) already normalised.
    ``fvp_rows`` (indices into the batch) restricts the Fisher-vector products, and so the step
    size, to those decisions (rllab's ``subsample_factor``); the gradient and the line search always
    use the whole batch."""
    fwd = net.forward(obs)
    logp_old = log_softmax(fwd.logits)
    probs = logp_old.exp()
    entropy = -float((probs * logp_old).sum(dim=0).mean(dtype=torch.float64))
    surr0 = float(adv.mean(dtype=torch.float64))  # the surrogate at theta_old: every ratio is 1

    grad = surrogate_gradient(net, fwd, probs, actions, adv)
    fvp = fisher_vector_product(net, fwd if fvp_rows is None else fwd.rows(fvp_rows), cg_damping)
    direction = conjugate_gradient(fvp, grad, cg_iters)
    shs = float(direction @ fvp(direction))
    if not shs > 0.0:  # zero gradient (e.g. all advantages equal): nothing to do
        return TRPOStats(0.0, entropy, surr0, surr0, 0, False)
    full_step = np.sqrt(2.0 * max_kl / shs) * direction

    accepted, backtracks, surr1, kl = line_search(
        net, lambda: surrogate_and_kl(net, obs, actions, adv, logp_old), full_step, surr0, max_kl,
        backtrack_ratio, max_backtracks)
    return TRPOStats(kl, entropy, surr0, surr1, backtracks, accepted)
