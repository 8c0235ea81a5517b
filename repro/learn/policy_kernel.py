"""The shared categorical tanh-MLP policy evaluated one decision at a time in compiled code: the
arithmetic of the :class:`repro.learn.policy.Sampler`.

Engines hand the policy one round of decisions at a time, and the sampler evaluates it row by row
with the functions here, whatever the round's size. The arithmetic is the network's, in float32:
each layer's sums in input order, then the bias, then tanh (:func:`tanh32`, correctly rounded).
It is the same on every CPU: numba reorders no sums and fuses no multiply-adds without fast-math,
while numpy's BLAS, which blocks its sums by CPU, stays out of it (:mod:`repro.runs.kernels`).
tests/test_policy_network.py checks these layers, the torch module and the derivative products of
:mod:`repro.learn.network` against one spec of the network.

numba caches a compiled kernel under its own source file's timestamp only, so kernels elsewhere
that call these (the sampler's) keep a stale copy after an edit here: ``make clean`` removes the
caches.
"""

from __future__ import annotations

import math
import numpy as np
from numba import njit


@njit(cache=True)
def sample_row(logits, u, cdf):
    """An action ~ softmax(logits) by inverse CDF with the uniform u, in float64: the number of
    cumulative unnormalised probabilities <= u times their total, capped at the last action against
    rounding at the top. ``cdf`` is float64 scratch of len(logits) entries."""
    n = len(logits)
    top = logits[0]
    for j in range(1, n):
        top = max(top, logits[j])
    total = 0.0
    for j in range(n):
        total += np.exp(np.float64(logits[j]) - top)
        cdf[j] = total
    target = u * total
    a = 0
    for j in range(n):
        if cdf[j] <= target:
            a += 1
    return min(a, n - 1)


_MID = 0.3125
_C = [math.exp(-_MID) * (-1.0) ** i / math.factorial(i) for i in range(13)]
(_C0, _C1, _C2, _C3, _C4, _C5, _C6, _C7, _C8, _C9, _C10, _C11, _C12) = _C


@njit(cache=True, inline="always", error_model="numpy")
def tanh32(v):
    """tanh of a float32, computed in float64 and rounded once: libm's tanh costs 30-45 ns a call
    on these machines and is not vectorised, 64 calls per decision of the default network; this is
    plain arithmetic that vectorises (about 4 ns). e^-2t = (e^-(MID + x))^32 with |x| <= MID, the
    inner exponential by its Taylor series to degree 12 (truncation below 1e-16); below t = 1e-3
    the series of tanh itself, where 1 - e^-2t would cancel. A test compares it with numpy's
    float64 tanh rounded to float32 over millions of arguments. (error_model="numpy": Python's
    division-by-zero check would stop the vectorisation.)"""
    a = abs(np.float64(v))
    t = 10.0 if a > 10.0 else a  # tanh(10) rounds to 1 in float32; NaN stays NaN
    x = t * (2.0 / 32.0) - _MID
    e = ((((((((((((_C12 * x + _C11) * x + _C10) * x + _C9) * x + _C8) * x + _C7) * x + _C6) * x
                + _C5) * x + _C4) * x + _C3) * x + _C2) * x + _C1) * x + _C0)
    e *= e
    e *= e
    e *= e
    e *= e
    e *= e
    t2 = t * t
    out = t * (1.0 - t2 * (1.0 / 3.0 - t2 * (2.0 / 15.0))) if t < 1e-3 else (1.0 - e) / (1.0 + e)
    return np.float32(math.copysign(out, v))


@njit(cache=True, error_model="numpy")
def logits_into(obs, weights, biases, mean, scale, x, y):
    """The network's logits (float32) for one raw observation ``obs``, computed in the float32
    scratch ``x`` and ``y`` (each at least as long as the observation and every layer) and
    returned as a view of ``x``."""
    for i in range(len(obs)):
        x[i] = np.float32((obs[i] - mean[i]) * scale[i])
    last = len(weights) - 1
    for k in range(len(weights)):
        w, b = weights[k], biases[k]
        n_in, n_out = w.shape
        out = y[:n_out]
        out[:] = 0.0
        # four inputs per pass along the outputs (vectorised): each sum is loaded and stored once
        # per four of its terms, which it still adds one at a time in input order
        for i in range(0, n_in - n_in % 4, 4):
            x0, x1, x2, x3 = x[i], x[i + 1], x[i + 2], x[i + 3]
            w0, w1, w2, w3 = w[i], w[i + 1], w[i + 2], w[i + 3]
            for j in range(out.shape[0]):
                out[j] = (((out[j] + x0 * w0[j]) + x1 * w1[j]) + x2 * w2[j]) + x3 * w3[j]
        for i in range(n_in - n_in % 4, n_in):
            xi, wi = x[i], w[i]
            for j in range(out.shape[0]):
                out[j] += xi * wi[j]
        if k < last:
            for j in range(n_out):
                x[j] = tanh32(out[j] + b[j])
        else:
            for j in range(n_out):
                x[j] = out[j] + b[j]
    return x[:weights[last].shape[1]]


@njit(cache=True)
def width(obs_dim, weights):
    """The length :func:`logits_into`'s scratch needs."""
    out = obs_dim
    for w in weights:
        out = max(out, w.shape[1])
    return out


@njit(cache=True)
def logits_row(obs, weights, biases, mean, scale):
    """The network's logits (float32) for one raw observation ``obs``."""
    n = width(len(obs), weights)
    return logits_into(obs, weights, biases, mean, scale, np.empty(n, np.float32),
                       np.empty(n, np.float32))


@njit(cache=True)
def act_row(obs, weights, biases, mean, scale, u):
    """The action for one raw observation ``obs`` with the uniform ``u``."""
    logits = logits_row(obs, weights, biases, mean, scale)
    return sample_row(logits, u, np.empty(len(logits)))
