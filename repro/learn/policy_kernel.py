"""The shared categorical tanh-MLP policy evaluated one decision at a time in compiled code: the
arithmetic of the :class:`repro.learn.policy.Sampler`.

Engines hand the policy one round of decisions at a time, and the sampler evaluates a small round
row by row with the functions here (a large one in blocks, with the same sums:
:class:`~repro.learn.policy.Sampler`). The arithmetic is the network's, in float32:
each layer's sums in input order, then the bias, then tanh (:func:`tanh32`, correctly rounded).
It is the same on every CPU: numba reorders no sums and fuses no multiply-adds without fast-math,
while numpy's BLAS, which blocks its sums by CPU, stays out of it (:mod:`repro.runs.kernels`).
tests/test_policy_network.py checks these layers, the torch module and the derivative products of
:mod:`repro.learn.network` against one spec of the network. :func:`tanh64` and :func:`sigmoid64`
are their float64 counterparts, plain arithmetic that vectorises, for the recurrent policy
(:mod:`repro.learn.gru_kernel`) and the float64 networks of the tests.

numba compiles a kernel for each type of its arguments and types a tuple by its length. The
row-by-row kernels here take a network's per-layer arrays as a plain tuple, so that they are
compiled for its depth (a round of a few rows costs a quarter less than with a depth known only at
run time); the kernels that work a chunk or block of decisions at a time (the sampler's blocks,
:mod:`repro.learn.network`) take them as :func:`slots`, tuples of :data:`LAYER_SLOTS` entries, so
that networks of one to four layers share one compilation per dtype, and find the depth with
:func:`depth`.

numba caches a compiled kernel under its own source file's timestamp only, so kernels elsewhere
that call these (the sampler's) keep a stale copy after an edit here: ``make clean`` removes the
caches.
"""

from __future__ import annotations

import math
import numpy as np
from numba import njit

LAYER_SLOTS = 4
"""The entries of the tuples that carry a network's per-layer arrays into compiled code: a
network of up to this many layers fills them, a deeper one a multiple of them."""


def slots(arrays, layers: int, dtype, ndim: int) -> tuple:
    """``arrays`` (one per layer, or one per hidden layer, of a network of ``layers`` layers) as the
    kernels take them: padded with empty arrays of ``dtype`` and ``ndim`` dimensions to ``layers``
    rounded up to a whole number of :data:`LAYER_SLOTS`."""
    count = -(-layers // LAYER_SLOTS) * LAYER_SLOTS
    return tuple(arrays) + (np.empty((0,) * ndim, dtype),) * (count - len(arrays))


@njit(cache=True, inline="always")
def depth(layers):
    """The layers of a network whose per-layer arrays ``layers`` are :func:`slots`: its non-empty
    entries (a layer has at least one unit and one input)."""
    n = 0
    for w in layers:
        if w.size > 0:
            n += 1
    return n


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


_INV_LN2 = 1.0 / math.log(2.0)
_LN2_HI = 6.93147180369123816490e-01
"""ln 2 to 32 significant bits: k ln 2 of an integer |k| < 2^20 is exact."""
_LN2_LO = 1.90821492927058770002e-10
"""ln 2 - _LN2_HI."""
_E = [1.0 / math.factorial(i) for i in range(14)]
(_, _, _E2, _E3, _E4, _E5, _E6, _E7, _E8, _E9, _E10, _E11, _E12, _E13) = _E


@njit(cache=True, inline="always", error_model="numpy")
def _exp_parts(y, low):
    """(2^k, e^r - 1) with y = k ln 2 + r, |r| <= ln 2 / 2 + 1e-9, for y <= 0 (k from y clamped
    at ``low`` >= -708, so that 2^k is a normal number, and from a finite number where y is NaN,
    whose r is NaN). Cody and Waite's reduction, then e^r - 1 by its Taylor series to degree 13
    (truncation below 2e-18 of it), r + r^2 (1/2 + r (1/6 + ...)) by Horner: about one rounding
    of e^r - 1. 2^k is built from its bits."""
    yk = y if y >= low else low
    k = math.floor(yk * _INV_LN2 + 0.5)
    kf = np.float64(k)
    r = (y - kf * _LN2_HI) - kf * _LN2_LO
    em = r + r * r * (_E2 + r * (_E3 + r * (_E4 + r * (_E5 + r * (_E6 + r * (_E7 + r * (
        _E8 + r * (_E9 + r * (_E10 + r * (_E11 + r * (_E12 + r * _E13)))))))))))
    return np.int64((k + 1023) << 52).view(np.float64), em


@njit(cache=True, inline="always", error_model="numpy")
def tanh64(v):
    """tanh of a float64 in plain float64 arithmetic that vectorises (libm's tanh is not
    vectorised and costs about 6 times as much here): with E = e^-2|v| - 1 (:func:`_exp_parts`,
    2^k (e^r - 1) + (2^k - 1)), tanh |v| = -E / (2 + E), where nothing cancels, so that the result
    is within 2.5 units in the last place (a test compares it with the 80-bit tanh); 1 beyond
    |v| = 20, where tanh rounds to 1; the sign of v; NaN stays NaN."""
    a = abs(v)
    t = 20.0 if a > 20.0 else a
    p, em = _exp_parts(-2.0 * t, -40.0)
    e = p * em + (p - 1.0)
    return math.copysign(-e / (2.0 + e), v)


@njit(cache=True, inline="always", error_model="numpy")
def sigmoid64(z):
    """1 / (1 + e^-z) of a float64 in plain float64 arithmetic that vectorises: with e = e^-|z|
    (:func:`_exp_parts`, 2^k + 2^k (e^r - 1); 0 below |z| = 708, where it is below the smallest
    normal number), 1 / (1 + e) for z >= 0 and e / (1 + e) below, within 2.5 units in the last
    place; NaN stays NaN."""
    y = -abs(z)
    p, em = _exp_parts(y, -708.0)
    e = p + p * em
    e = 0.0 if y < -708.0 else e
    return (1.0 if z >= 0.0 else e) / (1.0 + e)


@njit(cache=True, error_model="numpy")
def logits_into(obs, weights, biases, mean, scale, x, y):
    """The network's logits (float32) for one raw observation ``obs``, computed in the float32
    scratch ``x`` and ``y`` (each at least as long as the observation and every layer) and
    returned as a view of ``x``. ``weights`` (inputs, outputs) and ``biases``: a tuple with one
    array per layer."""
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
