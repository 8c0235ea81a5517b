"""The policy network's arithmetic in training: a forward pass that keeps what the derivatives
need, and the Jacobian products a TRPO step is made of, for the tanh MLP of
:func:`repro.learn.policy.mlp`, as compiled loops whose every sum runs in a fixed order.

Why compiled loops, and not torch: torch's matrix products run in MKL, which picks its kernels by
the CPU's vendor as well as its instruction set (its reproducibility modes hold across vendors only
on its slowest, SSE2 path), so the same run gave other bits on an AMD CPU than on an Intel one.
These loops call no library: without fast-math, LLVM neither reorders their sums nor fuses their
multiply-adds, so they give the same bits on every CPU, whatever width it vectorises them to
(:mod:`repro.runs.kernels`). A Fisher-vector product is one pass over the batch (forward-mode
product, KL weighting, backward product, weight gradient) while each chunk of it is in the cache.

The order of the sums. Decisions are computed a chunk at a time, side by side: within a
decision, a layer's sum runs in input order, then adds the bias (the sampler's order,
:func:`repro.learn.policy_kernel.logits_into`, so the step differentiates the logits the batch was
sampled with). A sum over decisions (a weight's gradient) keeps :data:`LANES` partial sums, adds
each chunk's terms to them in decision order, and adds the lanes in order at the end.

Arithmetic: a decision's products run in the network's dtype (float32 in training), as torch's
did; a sum over decisions adds chunks of those in that dtype to float64 per-lane sums; the KL
weighting, log-probabilities, the surrogate and the KL are float64. tests/test_learn_network.py
checks every product against autograd on a float64 module, and the forward pass against the
sampler bit for bit.

Layout: inputs, activations and logits are feature-major, (units, N rounded up to a whole
:data:`CHUNK`); the padding columns hold zero inputs, whose terms are never used or weigh 0. A
layer's weights are (outputs, inputs), as torch keeps them; flat parameter vectors follow torch's
``parameters_to_vector`` order (per layer: the weight row by row, then the bias). The per-layer
arrays reach the compiled loops as :func:`~repro.learn.policy_kernel.slots`, so that networks of
every depth up to four layers share their compilations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import torch
from numba import njit, types
from numba.extending import overload
from torch import nn

from repro.learn.policy_kernel import depth, slots, tanh32, tanh64

LANES = 64
"""The partial sums that a sum over decisions keeps: with :data:`CHUNK`, this, not the CPU, fixes
the order in which a weight's gradient is summed."""
CHUNK = 1024
"""Decisions computed side by side, a multiple of LANES (their rows stay in the cache). Within a
decision the sums are the decision's own, so the chunk fixes only how sums over decisions group."""


def activation(v):
    """tanh in the dtype of ``v``: the sampler's :func:`~repro.learn.policy_kernel.tanh32` for a
    float32, :func:`~repro.learn.policy_kernel.tanh64` for a float64 (the recurrent policy's
    feature network, :mod:`repro.learn.gru`, and the tests' networks). Compiled code only."""
    raise NotImplementedError("activation is compiled in; call it from njit code")


@overload(activation, inline="always")
def _activation(v):
    if isinstance(v, types.Float) and v.bitwidth == 32:
        return lambda v: tanh32(v)
    return lambda v: tanh64(v)


def padded(n: int) -> int:
    """``n`` decisions rounded up to whole chunks."""
    return -(-n // CHUNK) * CHUNK


@dataclass
class Forward:
    """One forward pass over a batch of ``n`` decisions, feature-major, with what the Jacobian
    products reuse."""

    n: int
    x: np.ndarray
    """Inputs, (in_dim, padded n), in the network's dtype."""
    hidden: tuple[np.ndarray, ...]
    """tanh activations of each hidden layer, (units, padded n)."""
    slopes: tuple[np.ndarray, ...]
    """tanh' = 1 - h^2 of each hidden layer, (units, padded n), computed in float64."""
    logits: np.ndarray
    """Outputs, (n_actions, padded n)."""
    _logp: np.ndarray | None = field(default=None, repr=False)
    _probs: np.ndarray | None = field(default=None, repr=False)

    def log_probs(self) -> np.ndarray:
        """log pi(. | o), (n, n_actions), float64 (computed once: the step and its Fisher products
        both need them; not to be written to)."""
        if self._logp is None:
            self._logp = np.empty((self.n, len(self.logits)))
            log_softmax_into(self.logits, self._logp)
        return self._logp

    def probs(self) -> np.ndarray:
        """pi(. | o) = exp(log_probs()), (n, n_actions), float64, by libm's exp (numpy's own exp
        has CPU-specific kernels); computed once: the entropy, the gradient, the Fisher products
        and every KL against this policy use them. Not to be written to."""
        if self._probs is None:
            self._probs = libm_exp(self.log_probs())
        return self._probs

    def rows(self, index: np.ndarray) -> Forward:
        """The same pass restricted to the batch entries ``index``."""
        return Forward(len(index), _columns(self.x, index),
                       tuple(_columns(h, index) for h in self.hidden),
                       tuple(_columns(s, index) for s in self.slopes),
                       _columns(self.logits, index))


def _columns(a: np.ndarray, index: np.ndarray) -> np.ndarray:
    out = np.zeros((len(a), padded(len(index))), a.dtype)
    out[:, :len(index)] = a[:, index]
    return out


def _padded_rows(a: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """(N, k) rows as a feature-major (k, padded N) array of ``dtype``, zero-padded."""
    out = np.zeros((a.shape[1], padded(len(a))), dtype)
    out[:, :len(a)] = a.T
    return out


class TanhMLP:
    """The ``Linear`` layers of a tanh MLP as arrays for the compiled loops, their parameters also
    seen as one flat float64 vector in ``parameters_to_vector`` order. The torch module stays the
    parameters' owner (checkpoints save it): :meth:`set_flat` writes both."""

    def __init__(self, net: nn.Sequential):
        self.linears = [m for m in net if isinstance(m, nn.Linear)]
        self.dtype = self.linears[0].weight.detach().numpy().dtype
        self.shapes = [(m.out_features, m.in_features) for m in self.linears]
        self.size = sum(o * i + o for o, i in self.shapes)
        self._read()

    def _read(self) -> None:
        with torch.no_grad():
            self.weights = tuple(m.weight.numpy().copy() for m in self.linears)
            """Per layer, the (outputs, inputs) weights."""
            self.biases = tuple(m.bias.numpy().copy() for m in self.linears)
        self._weight_slots = self._slots(self.weights, 2)
        """The weights as the compiled loops take them; likewise the biases."""
        self._bias_slots = self._slots(self.biases, 1)

    def _slots(self, arrays, ndim: int, dtype=None) -> tuple[np.ndarray, ...]:
        """Per-layer (or per-hidden-layer) arrays of ``ndim`` dimensions as the compiled loops take
        them, in the network's dtype unless given."""
        return slots(arrays, len(self.shapes), dtype or self.dtype, ndim)

    def _pass(self, fwd: Forward) -> tuple:
        """A pass's inputs, activations and slopes as the compiled loops take them."""
        return fwd.x, self._slots(fwd.hidden, 2), self._slots(fwd.slopes, 2)

    def _direction(self, v: np.ndarray) -> tuple:
        """A flat direction's per-layer (weights, biases), cast to the network's dtype, as the
        compiled loops take them."""
        vw, vb = self.split(np.asarray(v, dtype=self.dtype))
        return self._slots(vw, 2), self._slots(vb, 1)

    def get_flat(self) -> np.ndarray:
        return np.concatenate([np.concatenate([w.ravel(), b]) for w, b
                               in zip(self.weights, self.biases)]).astype(np.float64)

    def set_flat(self, theta: np.ndarray) -> None:
        """Write ``theta`` into the parameters (cast to their dtype)."""
        with torch.no_grad():
            for m, w, b in zip(self.linears, *self.split(theta)):
                m.weight.copy_(torch.from_numpy(w))
                m.bias.copy_(torch.from_numpy(b))
        self._read()

    def split(self, v: np.ndarray) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        """A flat vector as per-layer (weights, biases) pieces, in its dtype."""
        weights, biases, at = [], [], 0
        for out, inp in self.shapes:
            weights.append(np.ascontiguousarray(v[at:at + out * inp].reshape(out, inp)))
            biases.append(np.ascontiguousarray(v[at + out * inp:at + out * inp + out]))
            at += out * inp + out
        return tuple(weights), tuple(biases)

    def forward(self, x: np.ndarray | Forward) -> Forward:
        """The pass over inputs ``x`` (N, in_dim), or over the inputs of an earlier pass ``x``
        (a line search's trials)."""
        if isinstance(x, Forward):
            return self.forward_columns(x.x, x.n)
        return self.forward_columns(_padded_rows(x, self.dtype), len(x))

    def forward_columns(self, xt: np.ndarray, n: int) -> Forward:
        """The pass over ``n`` inputs given feature-major, ``xt`` (in_dim, padded n) in the
        network's dtype, zero beyond column n (kept by the pass, not copied)."""
        cols = xt.shape[1]
        hidden = tuple(np.empty((o, cols), self.dtype) for o, _ in self.shapes[:-1])
        slopes = tuple(np.empty((o, cols), self.dtype) for o, _ in self.shapes[:-1])
        logits = np.empty((self.shapes[-1][0], cols), self.dtype)
        _forward(xt, self._weight_slots, self._bias_slots, self._slots(hidden, 2),
                 self._slots(slopes, 2), logits)
        return Forward(n, xt, hidden, slopes, logits)

    def _accumulators(self) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        """Zeroed per-lane gradient sums: weights (outputs, inputs, LANES), biases (as the
        compiled loops take them)."""
        return (self._slots([np.zeros((o, i, LANES)) for o, i in self.shapes], 3, np.float64),
                self._slots([np.zeros((o, LANES)) for o, _ in self.shapes], 2, np.float64))

    def _flat(self, gw: tuple[np.ndarray, ...], gb: tuple[np.ndarray, ...]) -> np.ndarray:
        """Per-lane sums added in lane order, as one flat vector."""
        out = np.empty(self.size)
        _flatten(gw, gb, out)
        return out

    def jvp(self, fwd: Forward, v: np.ndarray) -> np.ndarray:
        """J v: the change of the logits (N, n_actions) along the direction ``v``."""
        return self.jvp_columns(fwd, v)[:, :fwd.n].T

    def jvp_columns(self, fwd: Forward, v: np.ndarray) -> np.ndarray:
        """J v feature-major: (n_actions, padded N), its padding columns the outputs' change at
        zero inputs."""
        out = np.empty((len(self.biases[-1]), fwd.x.shape[1]), self.dtype)
        _jvp(*self._pass(fwd), self._weight_slots, *self._direction(v), out)
        return out

    def vjp(self, fwd: Forward, g: np.ndarray) -> np.ndarray:
        """J' g: the gradient of sum(g * logits), g (N, n_actions), as a flat float64 vector."""
        return self.vjp_columns(fwd, _padded_rows(g, self.dtype))

    def vjp_columns(self, fwd: Forward, g: np.ndarray) -> np.ndarray:
        """:meth:`vjp` of ``g`` given feature-major, (n_actions, padded N) in the network's
        dtype, zero beyond column N."""
        gw, gb = self._accumulators()
        _vjp(*self._pass(fwd), g, self._weight_slots, gw, gb)
        return self._flat(gw, gb)

    def fisher_product(self, fwd: Forward, probs: np.ndarray, v: np.ndarray) -> np.ndarray:
        """J' M J v / N, M = diag(p) - p p' per decision: the Hessian of the mean KL in the
        parameters applied to ``v``, in one pass over the batch. ``probs``: pi(. | o) as
        :func:`probabilities` gives it for the pass ``fwd``."""
        gw, gb = self._accumulators()
        _fisher(*self._pass(fwd), probs, self._weight_slots, *self._direction(v), 1.0 / fwd.n,
                gw, gb)
        return self._flat(gw, gb)


def probabilities(fwd: Forward) -> np.ndarray:
    """pi(. | o) of the pass ``fwd``'s decisions (:meth:`Forward.probs`), feature-major and
    zero-padded as the batch."""
    return _padded_rows(fwd.probs(), np.float64)


# --- compiled loops ---------------------------------------------------------------------------
# A chunk's decisions are columns n0 .. n0 + CHUNK (u counts them). Every loop over u has its
# length from an array's shape, so that LLVM vectorises it (it would unroll a loop of constant
# length into scalar code); none of them sums across u.

@njit(cache=True, error_model="numpy")
def _forward(x, weights, biases, hidden, slopes, logits):
    last = depth(weights) - 1
    for n0 in range(0, x.shape[1], CHUNK):
        for k in range(last + 1):
            dst = logits if k == last else hidden[k]
            affine_chunk(dst, x if k == 0 else hidden[k - 1], n0, weights[k], biases[k])
            if k < last:
                for j in range(dst.shape[0]):
                    out, slope = dst[j, n0:n0 + CHUNK], slopes[k][j, n0:n0 + CHUNK]
                    for u in range(out.shape[0]):
                        out[u] = activation(out[u])
                        slope[u] = 1.0 - np.float64(out[u]) * out[u]


@njit(cache=True, inline="always", error_model="numpy")
def affine_chunk(dst, src, n0, w, b):
    """dst = W src + b on the chunk of columns from ``n0``: per unit, the sum of its inputs'
    terms in input order (:func:`add_products`), then the bias."""
    dst[:, n0:n0 + CHUNK] = 0.0
    add_products(dst, n0, src, n0, w)
    for j in range(w.shape[0]):
        out = dst[j, n0:n0 + CHUNK]
        for u in range(out.shape[0]):
            out[u] += b[j]


@njit(cache=True, inline="always", error_model="numpy")
def add_products(dst, d0, src, s0, coef):
    """dst[j, d0 + u] += src[i, s0 + u] coef[j, i] for every input i in turn, for every row j of
    ``coef`` and u < CHUNK: each element's terms are added one at a time in input order. Four rows
    j and four inputs i are done in one pass over the chunk, their sums held in registers (the
    inner loop over the four inputs has a constant length, so LLVM unrolls it inside the loop
    over u, which it vectorises): each element of ``dst`` is loaded and stored once per four
    inputs, each of ``src`` once per four rows. ``src`` is indexed with an unsigned column, which
    numba does not wrap around, so its loads along u are contiguous."""
    rows, inputs = coef.shape
    i4, j4 = inputs - inputs % 4, rows - rows % 4
    for j in range(0, j4, 4):
        o0, o1 = dst[j, d0:d0 + CHUNK], dst[j + 1, d0:d0 + CHUNK]
        o2, o3 = dst[j + 2, d0:d0 + CHUNK], dst[j + 3, d0:d0 + CHUNK]
        for i in range(0, i4, 4):
            for u in range(o0.shape[0]):
                a0, a1, a2, a3 = o0[u], o1[u], o2[u], o3[u]
                col = np.uint64(s0 + u)
                for di in range(4):
                    v = src[i + di, col]
                    a0 += v * coef[j, i + di]
                    a1 += v * coef[j + 1, i + di]
                    a2 += v * coef[j + 2, i + di]
                    a3 += v * coef[j + 3, i + di]
                o0[u], o1[u], o2[u], o3[u] = a0, a1, a2, a3
        for i in range(i4, inputs):
            for u in range(o0.shape[0]):
                v = src[i, np.uint64(s0 + u)]
                o0[u] += v * coef[j, i]
                o1[u] += v * coef[j + 1, i]
                o2[u] += v * coef[j + 2, i]
                o3[u] += v * coef[j + 3, i]
    for j in range(j4, rows):
        out = dst[j, d0:d0 + CHUNK]
        for i in range(0, i4, 4):
            for u in range(out.shape[0]):
                a = out[u]
                col = np.uint64(s0 + u)
                for di in range(4):
                    a += src[i + di, col] * coef[j, i + di]
                out[u] = a
        for i in range(i4, inputs):
            for u in range(out.shape[0]):
                out[u] += src[i, np.uint64(s0 + u)] * coef[j, i]


@njit(cache=True, inline="always", error_model="numpy")
def _jvp_chunk(n0, x, hidden, slopes, weights, vw, vb, da, dy):
    """J v for the chunk of decisions at ``n0``: rows [:n_actions] of ``dy`` (width, CHUNK);
    ``da`` is scratch of the same shape. Per unit, the bias's change, then the terms of the
    weights' change in input order, then (past the first layer) those of the inputs' change."""
    last = depth(weights) - 1
    for k in range(last + 1):
        w, dw, db = weights[k], vw[k], vb[k]
        src = x if k == 0 else hidden[k - 1]
        for j in range(w.shape[0]):
            dy[j, :] = db[j]
        add_products(dy, 0, src, n0, dw)
        if k > 0:
            add_products(dy, 0, da, 0, w)
        if k < last:
            for j in range(w.shape[0]):
                s, out, a = slopes[k][j, n0:n0 + CHUNK], dy[j], da[j]
                for u in range(out.shape[0]):
                    a[u] = out[u] * s[u]


@njit(cache=True, inline="always", error_model="numpy")
def _backward_chunk(n0, slopes, weights, deltas):
    """Carry the output cotangent in the last layer's ``deltas`` (the chunk of decisions at
    ``n0``) back to every hidden layer's ``deltas[k]``: per unit, the terms of the outputs in
    output order, then times tanh'."""
    for k in range(depth(weights) - 1, 0, -1):
        prev = deltas[k - 1]
        prev[:, :] = 0.0
        add_products(prev, 0, deltas[k], 0, weights[k].T)
        for i in range(prev.shape[0]):
            p, s = prev[i], slopes[k - 1][i, n0:n0 + CHUNK]
            for u in range(p.shape[0]):
                p[u] *= s[u]


@njit(cache=True, inline="always", error_model="numpy")
def _accumulate(n0, x, hidden, deltas, gw, gb):
    """Add the terms of the chunk at ``n0`` to every layer's per-lane gradient sums ``gw``
    ((outputs, inputs, LANES)) and ``gb`` ((outputs, LANES)): lane u of a weight's sum gets
    delta_j x_i of the chunk's decisions u, u + LANES, u + 2 LANES, ... in that order, summed in the
    network's dtype, then added in float64."""
    for k in range(depth(gw)):
        accumulate_layer(n0, x if k == 0 else hidden[k - 1], deltas[k], gw[k], gb[k])


@njit(cache=True, error_model="numpy")
def accumulate_layer(n0, src, d, g, gb):
    """:func:`_accumulate` for one layer, inputs ``src`` and cotangents ``d``.

    The loop over a lane's CHUNK / LANES terms has a constant length, so LLVM unrolls it inside
    the loop over lanes, which it vectorises: the lanes' sums stay in registers (columns unsigned,
    as in :func:`add_products`). Four outputs j share each load of an input's row. Their sums
    go to ``lanes``, scratch allocated here, before they are added in float64: LLVM vectorises the
    loop only where its stores cannot overlap its many loads, which it knows of memory allocated
    here and not of arrays passed in."""
    zero = np.zeros(1, src.dtype)[0]
    lanes = np.empty((4, LANES), src.dtype)
    rows = g.shape[0]
    for j in range(0, rows - rows % 4, 4):
        for u in range(lanes.shape[1]):
            a0 = a1 = a2 = a3 = zero
            for c in range(0, CHUNK, LANES):
                col = np.uint64(c + u)
                a0 += d[j, col]
                a1 += d[j + 1, col]
                a2 += d[j + 2, col]
                a3 += d[j + 3, col]
            lanes[0, u], lanes[1, u], lanes[2, u], lanes[3, u] = a0, a1, a2, a3
        for q in range(4):
            _add_lane_sums(gb[j + q], lanes[q])
        for i in range(g.shape[1]):
            for u in range(lanes.shape[1]):
                a0 = a1 = a2 = a3 = zero
                for c in range(0, CHUNK, LANES):
                    col = np.uint64(c + u)
                    v = src[i, np.uint64(n0 + c + u)]
                    a0 += d[j, col] * v
                    a1 += d[j + 1, col] * v
                    a2 += d[j + 2, col] * v
                    a3 += d[j + 3, col] * v
                lanes[0, u], lanes[1, u], lanes[2, u], lanes[3, u] = a0, a1, a2, a3
            for q in range(4):
                _add_lane_sums(g[j + q, i], lanes[q])
    for j in range(rows - rows % 4, rows):
        for u in range(lanes.shape[1]):
            acc = zero
            for c in range(0, CHUNK, LANES):
                acc += d[j, np.uint64(c + u)]
            lanes[0, u] = acc
        _add_lane_sums(gb[j], lanes[0])
        for i in range(g.shape[1]):
            for u in range(lanes.shape[1]):
                acc = zero
                for c in range(0, CHUNK, LANES):
                    acc += d[j, np.uint64(c + u)] * src[i, np.uint64(n0 + c + u)]
                lanes[0, u] = acc
            _add_lane_sums(g[j, i], lanes[0])


@njit(cache=True, inline="always", error_model="numpy")
def _add_lane_sums(out, add):
    """out += add (float64 += the network's dtype)."""
    for u in range(out.shape[0]):
        out[u] += add[u]


@njit(cache=True, error_model="numpy")
def _chunk_deltas(weights):
    """Per layer, a (units, CHUNK) buffer of cotangents in the network's dtype."""
    return [np.empty((w.shape[0], CHUNK), w.dtype) for w in weights]


@njit(cache=True, error_model="numpy")
def _width(weights):
    out = 0
    for w in weights:
        out = max(out, w.shape[0], w.shape[1])
    return out


@njit(cache=True, error_model="numpy")
def _jvp(x, hidden, slopes, weights, vw, vb, out):
    width = _width(weights)
    da, dy = np.empty((width, CHUNK), x.dtype), np.empty((width, CHUNK), x.dtype)
    for n0 in range(0, x.shape[1], CHUNK):
        _jvp_chunk(n0, x, hidden, slopes, weights, vw, vb, da, dy)
        out[:, n0:n0 + CHUNK] = dy[:out.shape[0]]


@njit(cache=True, error_model="numpy")
def _vjp(x, hidden, slopes, g, weights, gw, gb):
    deltas, last = _chunk_deltas(weights), depth(weights) - 1
    for n0 in range(0, x.shape[1], CHUNK):
        deltas[last][:, :] = g[:, n0:n0 + CHUNK]
        _backward_chunk(n0, slopes, weights, deltas)
        _accumulate(n0, x, hidden, deltas, gw, gb)


@njit(cache=True, error_model="numpy")
def _fisher(x, hidden, slopes, probs, weights, vw, vb, scale, gw, gb):
    width = _width(weights)
    da, dy = np.empty((width, CHUNK), x.dtype), np.empty((width, CHUNK), x.dtype)
    deltas, last = _chunk_deltas(weights), depth(weights) - 1
    mean = np.empty(CHUNK)
    for n0 in range(0, x.shape[1], CHUNK):
        _jvp_chunk(n0, x, hidden, slopes, weights, vw, vb, da, dy)
        kl_weighting(n0, probs, dy, scale, mean, deltas[last])
        _backward_chunk(n0, slopes, weights, deltas)
        _accumulate(n0, x, hidden, deltas, gw, gb)


@njit(cache=True, inline="always", error_model="numpy")
def kl_weighting(n0, probs, jv, scale, mean, out):
    """out = p (jv - p . jv) scale per decision (column) of the chunk at ``n0``: M J v / N of a
    block, in float64, p . jv summed in action order. Rows of ``probs`` are taken as contiguous
    slices (a slice across its rows would be strided, and the loops would not vectorise)."""
    mean[:] = 0.0
    for a in range(len(probs)):
        pa, ja = probs[a, n0:n0 + CHUNK], jv[a]
        for u in range(mean.shape[0]):
            mean[u] += pa[u] * ja[u]
    for a in range(len(probs)):
        pa, ja, oa = probs[a, n0:n0 + CHUNK], jv[a], out[a]
        for u in range(mean.shape[0]):
            oa[u] = pa[u] * (ja[u] - mean[u]) * scale


@njit(cache=True, error_model="numpy")
def _flatten(gw, gb, out):
    at = 0
    for k in range(depth(gw)):
        g, b = gw[k], gb[k]
        for j in range(g.shape[0]):
            for i in range(g.shape[1]):
                total = 0.0
                for u in range(LANES):
                    total += g[j, i, u]
                out[at] = total
                at += 1
        for j in range(b.shape[0]):
            total = 0.0
            for u in range(LANES):
                total += b[j, u]
            out[at] = total
            at += 1


@njit(cache=True, error_model="numpy")
def log_softmax_into(logits, out):
    for n in range(out.shape[0]):
        top = np.float64(logits[0, n])
        for a in range(1, out.shape[1]):
            top = max(top, np.float64(logits[a, n]))
        total = 0.0
        for a in range(out.shape[1]):
            total += math.exp(np.float64(logits[a, n]) - top)
        log_total = math.log(total)
        for a in range(out.shape[1]):
            out[n, a] = np.float64(logits[a, n]) - top - log_total


@njit(cache=True, error_model="numpy")
def libm_exp(logp):
    """exp of every entry of a 2-d float64 array, by libm (numpy's own exp has CPU-specific
    kernels)."""
    out = np.empty(logp.shape)
    for n in range(logp.shape[0]):
        for a in range(logp.shape[1]):
            out[n, a] = math.exp(logp[n, a])
    return out
