"""One TRPO policy update, split into small functions (the layout follows sb3-contrib's TRPO; the
constants follow rllab's ConjugateGradientOptimizer, which produced the paper's results).

maximise  L(theta) = mean_k  pi_theta(a_k|o_k) / pi_old(a_k|o_k) * A_k
s.t.      mean_k KL(pi_old(.|o_k) || pi_theta(.|o_k)) <= max_kl

The natural-gradient direction s solves F s = grad L by conjugate gradient, F being the Hessian of
the mean KL at theta_old (the Fisher matrix, applied as a product, never formed). The step
sqrt(2 max_kl / s'Fs) s would meet the KL bound exactly under the quadratic model; a backtracking
line search shrinks it until the true KL is within the bound AND the surrogate improved, and
otherwise leaves the parameters where they were.

The network's products are compiled loops (:mod:`repro.learn.network`), and so is every sum here
(:func:`dot`, :func:`surrogate_and_kl`): no BLAS, whose kernels sum in an order of the CPU's
choosing, takes part. Batches: observations (N, obs_dim) in the network's dtype; log-probabilities
(N, n_actions) and everything else float64.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from numba import njit

from repro.learn.network import Forward, TanhMLP, libm_exp, probabilities


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


@njit(cache=True)
def dot(a, b):
    """a . b of two float64 vectors, summed in index order."""
    total = 0.0
    for i in range(a.shape[0]):
        total += a[i] * b[i]
    return total


def conjugate_gradient(matvec: Callable[[np.ndarray], np.ndarray], b: np.ndarray,
                       iters: int, residual_tol: float = 1e-10) -> np.ndarray:
    """Approximately solve A x = b for symmetric positive-definite A given only x -> A x."""
    x = np.zeros_like(b)
    r = b.copy()
    p = b.copy()
    rr = dot(r, r)
    for _ in range(iters):
        if rr < residual_tol:
            break
        ap = matvec(p)
        alpha = rr / dot(p, ap)
        x += alpha * p
        r -= alpha * ap
        rr_new = dot(r, r)
        p = r + (rr_new / rr) * p
        rr = rr_new
    return x


def mean_kl(logp_old: np.ndarray, logp_new: np.ndarray) -> float:
    """Mean over decisions of KL(old || new), both (N, n_actions) log-probabilities."""
    return mean_kl_given(libm_exp(np.ascontiguousarray(logp_old, np.float64)), logp_old, logp_new)


@njit(cache=True)
def mean_kl_given(p_old, logp_old, logp_new):
    """The mean KL with the old policy's probabilities ``p_old`` = exp(``logp_old``) given (the
    step computes them once, :meth:`~repro.learn.network.Forward.probs`)."""
    total = 0.0
    for n in range(logp_old.shape[0]):
        row = 0.0
        for a in range(logp_old.shape[1]):
            row += p_old[n, a] * (logp_old[n, a] - logp_new[n, a])
        total += row
    return total / logp_old.shape[0]


def surrogate_gradient(net: TanhMLP, fwd: Forward, actions: np.ndarray,
                       adv: np.ndarray) -> np.ndarray:
    """grad L at theta_old = mean_k A_k grad log pi(a_k|o_k), at the parameters of the pass
    ``fwd``. The derivative of log pi(a|o) with respect to the logits is onehot(a) - pi(.|o), so
    this is one backward pass of those rows."""
    return net.vjp(fwd, score_rows(fwd.probs(), actions, adv))


@njit(cache=True)
def score_rows(probs, actions, adv):
    """(onehot(a_k) - pi(.|o_k)) A_k / N, row by row."""
    n = actions.shape[0]
    out = np.empty(probs.shape)
    for k in range(n):
        w = adv[k] / n
        for a in range(probs.shape[1]):
            out[k, a] = -probs[k, a] * w
        out[k, actions[k]] += w
    return out


def fisher_vector_product(net: TanhMLP, fwd: Forward,
                          damping: float) -> Callable[[np.ndarray], np.ndarray]:
    """v -> (F + damping I) v, F the Hessian of the mean KL at the parameters of ``fwd``.

    For a categorical policy that Hessian is J' M J / N, J the Jacobian of the logits with respect
    to the parameters and M = diag(p) - p p' the Hessian of the KL in the logits, per decision. So a
    product is a forward-mode pass (J v), a weighting, and a backward pass (J' u), no second
    derivatives of the network: :meth:`TanhMLP.fisher_product`, one pass over the batch.
    """
    probs = probabilities(fwd)

    def fvp(v: np.ndarray) -> np.ndarray:
        return net.fisher_product(fwd, probs, v) + damping * v

    return fvp


def surrogate_and_kl(net: TanhMLP, old: Forward, actions: np.ndarray,
                     adv: np.ndarray) -> tuple[float, float]:
    """(L, mean KL(old || current)) at the network's current parameters against the pass ``old``
    (the parameters before the step): one forward pass over its inputs, which is what each
    line-search trial costs."""
    logp, logp_old = net.forward(old).log_probs(), old.log_probs()
    return surrogate_of(logp, logp_old, actions, adv), mean_kl_given(old.probs(), logp_old, logp)


@njit(cache=True)
def surrogate_of(logp, logp_old, actions, adv):
    total = 0.0
    for n in range(actions.shape[0]):
        a = actions[n]
        total += math.exp(logp[n, a] - logp_old[n, a]) * adv[n]
    return total / actions.shape[0]


def line_search(net: TanhMLP, evaluate: Callable[[], tuple[float, float]],
                full_step: np.ndarray, surrogate_before: float, max_kl: float,
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


def trpo_step(net: TanhMLP, obs: np.ndarray, actions: np.ndarray, adv: np.ndarray, *,
              max_kl: float, cg_iters: int, cg_damping: float, backtrack_ratio: float,
              max_backtracks: int, fvp_rows: np.ndarray | None = None) -> TRPOStats:
    """One constrained update of the logit network ``net`` on a batch: observations ``obs``
    (N, obs_dim) as the network sees them, ``actions`` (N,), ``adv`` (N,) float64, already
    normalised. ``fvp_rows`` (indices into the batch) restricts the Fisher-vector products, and so
    the step size, to those decisions (rllab's ``subsample_factor``); the gradient and the line
    search always use the whole batch."""
    actions = np.ascontiguousarray(actions, dtype=np.int64)
    adv = np.ascontiguousarray(adv, dtype=np.float64)
    fwd = net.forward(obs)
    logp_old = fwd.log_probs()
    # the mean of p log p, negated
    entropy = -mean_kl_given(fwd.probs(), logp_old, np.zeros_like(logp_old))
    surr0 = float(adv.mean())  # the surrogate at theta_old: every ratio is 1

    grad = surrogate_gradient(net, fwd, actions, adv)
    fvp = fisher_vector_product(net, fwd if fvp_rows is None else fwd.rows(fvp_rows), cg_damping)
    direction = conjugate_gradient(fvp, grad, cg_iters)
    shs = dot(direction, fvp(direction))
    if not shs > 0.0:  # zero gradient (e.g. all advantages equal): nothing to do
        return TRPOStats(0.0, entropy, surr0, surr0, 0, False)
    full_step = np.sqrt(2.0 * max_kl / shs) * direction

    accepted, backtracks, surr1, kl = line_search(
        net, lambda: surrogate_and_kl(net, fwd, actions, adv), full_step, surr0,
        max_kl, backtrack_ratio, max_backtracks)
    return TRPOStats(kl, entropy, surr0, surr1, backtracks, accepted)
