"""The learner's compiled kernels add every sum in the order their documentation states, bit for
bit: each is compared, byte for byte, with a plain loop that computes one decision (or one row of
features) at a time in that order (repro.learn.network's and repro.learn.baseline's docstrings).

The kernels reorganise the work for speed (several units and inputs per pass, sums held in
registers, rows of the Gram matrix taken in blocks, its triangle mirrored), which must change no
bit of any result; these references do none of that, so a kernel that regrouped a sum, fused a
multiply-add or skipped a term would differ here in the last bits, whatever the fingerprints of
tests/test_learner_fingerprint.py happen to exercise."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from numba import njit

from repro.learn import network
from repro.learn.baseline import LinearFeatureBaseline, _normal_equations
from repro.learn.network import CHUNK, LANES, TanhMLP, activation, padded
from repro.learn.policy_kernel import depth, slots


@njit(cache=True)
def _reference_pass(x, weights, biases, g, probs, vw, vb, scale, fisher):
    """Decision by decision over the padded batch ``x`` (in_dim, columns): the forward pass
    (hidden activations, slopes, logits), J v (``vw``, ``vb``) and the per-lane sums of the
    gradient of sum(c * logits), c the cotangent ``g`` (n_actions, columns), or, where ``fisher``,
    c = p (J v - p . J v) ``scale`` with ``probs`` p. Returns (logits, J v, flat gradient). The
    per-layer arrays as the kernels take them (``slots``)."""
    last = depth(weights) - 1
    cols = x.shape[1]
    logits = np.empty((weights[last].shape[0], cols), x.dtype)
    jv_out = np.empty_like(logits)
    lanes_w = [np.zeros((w.shape[0], w.shape[1], LANES)) for w in weights]
    lanes_b = [np.zeros((w.shape[0], LANES)) for w in weights]
    chunk_w = [np.zeros((w.shape[0], w.shape[1], LANES), x.dtype) for w in weights]
    chunk_b = [np.zeros((w.shape[0], LANES), x.dtype) for w in weights]
    for n in range(cols):
        if n % CHUNK == 0:
            for k in range(last + 1):
                chunk_w[k][:] = 0.0
                chunk_b[k][:] = 0.0
        # the forward pass and J v, a layer at a time
        acts, slopes = [x[:, n].copy()], []
        da = np.zeros(0, x.dtype)
        for k in range(last + 1):
            w, b, dw, db = weights[k], biases[k], vw[k], vb[k]
            y = np.empty(w.shape[0], x.dtype)
            t = np.empty(w.shape[0], x.dtype)
            for j in range(w.shape[0]):
                a = np.zeros(1, x.dtype)[0]
                for i in range(w.shape[1]):
                    a += acts[k][i] * w[j, i]
                y[j] = a + b[j]
                s = db[j]
                for i in range(w.shape[1]):
                    s += acts[k][i] * dw[j, i]
                if k > 0:
                    for i in range(w.shape[1]):
                        s += da[i] * w[j, i]
                t[j] = s
            if k < last:
                h = np.empty_like(y)
                slope = np.empty_like(y)
                for j in range(len(y)):
                    h[j] = activation(y[j])
                    slope[j] = 1.0 - np.float64(h[j]) * h[j]
                acts.append(h)
                slopes.append(slope)
                da = t * slope
            else:
                logits[:, n] = y
                jv_out[:, n] = t
        # the cotangent of the logits
        c = np.empty(len(t), x.dtype)
        if fisher:
            mean = 0.0
            for a in range(len(t)):
                mean += probs[a, n] * t[a]
            for a in range(len(t)):
                c[a] = probs[a, n] * (t[a] - mean) * scale
        else:
            c[:] = g[:, n]
        # back through the layers, each term added to its lane of this chunk's sums
        lane = n % CHUNK % LANES
        for k in range(last, -1, -1):
            w = weights[k]
            for j in range(w.shape[0]):
                chunk_b[k][j, lane] += c[j]
                for i in range(w.shape[1]):
                    chunk_w[k][j, i, lane] += c[j] * acts[k][i]
            if k > 0:
                prev = np.empty(w.shape[1], x.dtype)
                for i in range(w.shape[1]):
                    p = np.zeros(1, x.dtype)[0]
                    for j in range(w.shape[0]):
                        p += c[j] * w[j, i]
                    prev[i] = p * slopes[k - 1][i]
                c = prev
        if n % CHUNK == CHUNK - 1:
            for k in range(last + 1):
                lanes_w[k] += chunk_w[k]
                lanes_b[k] += chunk_b[k]
    size = 0
    for w in weights:
        size += w.shape[0] * w.shape[1] + w.shape[0]
    flat = np.empty(size)
    at = 0
    for k in range(last + 1):
        for j in range(weights[k].shape[0]):
            for i in range(weights[k].shape[1]):
                total = 0.0
                for u in range(LANES):
                    total += lanes_w[k][j, i, u]
                flat[at] = total
                at += 1
        for j in range(weights[k].shape[0]):
            total = 0.0
            for u in range(LANES):
                total += lanes_b[k][j, u]
            flat[at] = total
            at += 1
    return logits, jv_out, flat


SHAPES = [  # (obs_dim, hidden, n_actions, decisions): the authors' and suite's networks on
    (28, (32,), 6, 2 * CHUNK + 77),  # wildfire, and shapes that leave every remainder
    (28, (32, 32), 6, CHUNK),
    (7, (9, 6), 5, CHUNK + 3),
    (3, (5,), 1, 40),
]


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_network_kernels_sum_in_their_stated_order(shape, dtype):
    obs_dim, hidden, n_actions, n = shape
    torch.manual_seed(n)
    sizes = (obs_dim, *hidden, n_actions)
    layers: list[torch.nn.Module] = []
    for k in range(len(sizes) - 1):
        layers += [torch.nn.Linear(sizes[k], sizes[k + 1]), torch.nn.Tanh()]
    net = TanhMLP(torch.nn.Sequential(*layers[:-1]).to(dtype))
    rng = np.random.default_rng(n)
    obs = (3 * rng.normal(size=(n, obs_dim))).astype(net.dtype)
    v = rng.normal(size=net.size)
    g = rng.normal(size=(n, n_actions))
    fwd = net.forward(obs)
    probs = network.probabilities(fwd)
    layers = len(hidden) + 1
    vw, vb = (slots(a, layers, net.dtype, a[0].ndim) for a in net.split(v.astype(net.dtype)))
    gt = np.zeros((n_actions, padded(n)), net.dtype)
    gt[:, :n] = g.T
    args = (fwd.x, slots(net.weights, layers, net.dtype, 2),
            slots(net.biases, layers, net.dtype, 1))
    logits, jv, grad = _reference_pass(*args, gt, probs, vw, vb, 0.0, False)
    assert fwd.logits.tobytes() == logits.tobytes()
    assert net.jvp(fwd, v).tobytes() == np.ascontiguousarray(jv[:, :n].T).tobytes()
    assert net.vjp(fwd, g).tobytes() == grad.tobytes()
    _, _, fisher = _reference_pass(*args, gt, probs, vw, vb, 1.0 / n, True)
    assert net.fisher_product(fwd, probs, v).tobytes() == fisher.tobytes()


@njit(cache=True)
def _reference_normal_equations(x, returns):
    gram, rhs = np.zeros((x.shape[1], x.shape[1])), np.zeros(x.shape[1])
    for n in range(x.shape[0]):
        for a in range(x.shape[1]):
            for b in range(x.shape[1]):
                gram[a, b] += x[n, a] * x[n, b]
            rhs[a] += x[n, a] * returns[n]
    return gram, rhs


@pytest.mark.parametrize("obs_dim", [11, 35])  # a row of features within PANEL, and wider
@pytest.mark.parametrize("n", [1, 15, 16, 1000, 4099])
def test_normal_equations_sum_rows_in_batch_order(n, obs_dim):
    rng = np.random.default_rng(n)
    obs = 4 * rng.normal(size=(n, obs_dim))
    obs[rng.random(size=obs.shape) < 0.05] *= 1e3  # some clipped at 10
    index = rng.integers(0, 500, size=n).astype(np.float64)
    returns = 100 * rng.normal(size=n)
    gram, rhs = _normal_equations(obs, index, returns)
    want_gram, want_rhs = _reference_normal_equations(
        LinearFeatureBaseline.features(obs, index), returns)
    assert gram.tobytes() == want_gram.tobytes()
    assert rhs.tobytes() == want_rhs.tobytes()
