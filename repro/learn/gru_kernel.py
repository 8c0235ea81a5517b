"""The recurrent policy's arithmetic (:mod:`repro.learn.gru`) as compiled float64 loops whose every
sum runs in a fixed order: the GRU stepped over a batch's paths, its output layer, backpropagation
through time, the tangent pass of an exact Fisher-vector product, and the sampler's step of one
decision at a time. The feature MLP in front of the GRU is :mod:`repro.learn.network`'s (its
:class:`~repro.learn.network.TanhMLP` in float64), and so are the building blocks here: the
products over a chunk of columns (``add_products``), the per-lane sums over decisions
(``accumulate_layer``) and the KL weighting (``kl_weighting``).

Layout. A batch's D decisions are columns, feature-major as in :mod:`repro.learn.network`
((units, D rounded up to a whole CHUNK), zero beyond D), in step-major order: the paths are ranked
by decreasing length (ties in path order), and step t of the batch is the columns ``offsets[t]``
to ``offsets[t + 1]``, one per path longer than t, by rank. So the paths still running at step t
are the first ones of step t - 1, and a step of the GRU is a product over contiguous columns. The
GRU's weights are stacked by gate r, u, c as :class:`~repro.learn.gru.GRUCell` holds them.

The order of the sums. Within a decision a unit's sum runs in input order and then adds the bias,
as in the feature MLP: x-part xs_j = sum_i f_i W_x[j, i] + b_j, h-part hs_j = sum_k h_k W_h[j, k],
logits sum_k h'_k W_o[a, k] + b_o[a]; then r = sigmoid(xs_r + hs_r), u = sigmoid(xs_u + hs_u),
c = tanh(xs_c + r hs_c), h' = (1 - u) h + u c, by :func:`~repro.learn.policy_kernel.sigmoid64` and
:func:`~repro.learn.policy_kernel.tanh64`. The sampler (:func:`step_rows`) evaluates a decision in
exactly these operations, so the training pass differentiates the logits the batch was sampled
with, bit for bit. A tangent adds, per unit, the bias's change, the weights' change in input
order, then the inputs' change in input order (:func:`repro.learn.network._jvp_chunk`'s order). A
sum over decisions (a weight's gradient) keeps LANES partial sums over the columns in order, a
chunk at a time, and adds the lanes in order at the end.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from repro.learn.network import (CHUNK, LANES, accumulate_layer, add_products, affine_chunk,
                                 kl_weighting)
from repro.learn.policy_kernel import sigmoid64, tanh64


# --- columns: products over the whole batch, a chunk at a time --------------------------------

@njit(cache=True, error_model="numpy")
def linear_columns(src, w, b, out):
    """out = W src + b over every column, chunk by chunk as the MLP's layers
    (:func:`repro.learn.network.affine_chunk`)."""
    for n0 in range(0, src.shape[1], CHUNK):
        affine_chunk(out, src, n0, w, b)


@njit(cache=True, error_model="numpy")
def products_columns(src, w, out):
    """out = W src over every column (a cotangent carried back: ``w`` a transposed weight)."""
    for n0 in range(0, src.shape[1], CHUNK):
        out[:, n0:n0 + CHUNK] = 0.0
        add_products(out, n0, src, n0, w)


@njit(cache=True, error_model="numpy")
def tangent_columns(src, dsrc, w, dw, db, out):
    """out = db + dW src + W dsrc over every column: the change of a linear layer's outputs along
    a change ``dw``, ``db`` of its parameters and ``dsrc`` of its inputs."""
    for n0 in range(0, src.shape[1], CHUNK):
        for j in range(w.shape[0]):
            out[j, n0:n0 + CHUNK] = db[j]
        add_products(out, n0, src, n0, dw)
        add_products(out, n0, dsrc, n0, w)


@njit(cache=True, error_model="numpy")
def accumulate_columns(src, d, g, gb):
    """Add sum over columns of d src' to the per-lane sums ``g`` (outputs, inputs, LANES) and of
    d to ``gb`` (outputs, LANES), a chunk at a time
    (:func:`repro.learn.network.accumulate_layer`)."""
    buf = np.empty((d.shape[0], CHUNK))
    for n0 in range(0, src.shape[1], CHUNK):
        buf[:, :] = d[:, n0:n0 + CHUNK]
        accumulate_layer(n0, src, buf, g, gb)


@njit(cache=True, error_model="numpy")
def kl_weighting_columns(probs, jv, scale, out):
    """out = p (jv - p . jv) scale per column (M J v / N), probabilities ``probs`` feature-major
    and zero beyond the batch (:func:`repro.learn.network.kl_weighting`)."""
    mean = np.empty(CHUNK)
    buf, res = np.empty((jv.shape[0], CHUNK)), np.empty((jv.shape[0], CHUNK))
    for n0 in range(0, jv.shape[1], CHUNK):
        buf[:, :] = jv[:, n0:n0 + CHUNK]
        kl_weighting(n0, probs, buf, scale, mean, res)
        out[:, n0:n0 + CHUNK] = res


@njit(cache=True, error_model="numpy")
def kl_gradient_columns(probs, probs_old, scale, out):
    """out[a, c] = (p[c, a] - p_old[c, a]) scale for the batch's columns c: the gradient of the
    mean KL(old || current) in the logits (scale 1 / D), zero beyond them."""
    out[:, :] = 0.0
    for c in range(probs.shape[0]):
        for a in range(probs.shape[1]):
            out[a, c] = (probs[c, a] - probs_old[c, a]) * scale


@njit(cache=True, error_model="numpy")
def lane_totals(g, out):
    """out[m] = the sum of row m of per-lane sums ``g`` (M, LANES), lanes in order."""
    for m in range(g.shape[0]):
        total = 0.0
        for q in range(LANES):
            total += g[m, q]
        out[m] = total


# --- the GRU over the batch's steps -----------------------------------------------------------

@njit(cache=True, inline="always", error_model="numpy")
def _step_products(dst, src, s0, w):
    """dst[j, q] += sum_i src[i, s0 + q] w[j, i] for q < dst's width (any width)."""
    for b0 in range(0, dst.shape[1], CHUNK):
        add_products(dst, b0, src, s0 + b0, w)


@njit(cache=True, error_model="numpy")
def gru_forward(offsets, xs, wh, r, u, c, hsc, h, hprev):
    """The GRU over the steps of the batch whose x-parts (with the bias) are ``xs`` (3H, columns):
    fills, per column, the gates ``r``, ``u``, ``c``, the h-part of c's gate ``hsc`` (W_h h for
    its rows), the state after the decision ``h`` and the one before ``hprev`` (zero at a path's
    first step), each (H, columns)."""
    n_h = wh.shape[1]
    for t in range(len(offsets) - 1):
        o, n = offsets[t], offsets[t + 1] - offsets[t]
        hs = np.zeros((3 * n_h, n))
        if t > 0:
            po = offsets[t - 1]
            _step_products(hs, h, po, wh)
            for j in range(n_h):
                hprev[j, o:o + n] = h[j, po:po + n]
        for j in range(n_h):
            xr, xu, xc = xs[j, o:o + n], xs[n_h + j, o:o + n], xs[2 * n_h + j, o:o + n]
            hr, hu, hc = hs[j], hs[n_h + j], hs[2 * n_h + j]
            rj, uj, cj, hcj = r[j, o:o + n], u[j, o:o + n], c[j, o:o + n], hsc[j, o:o + n]
            hp, hj = hprev[j, o:o + n], h[j, o:o + n]
            for q in range(hj.shape[0]):
                rr = sigmoid64(xr[q] + hr[q])
                uu = sigmoid64(xu[q] + hu[q])
                cc = tanh64(xc[q] + rr * hc[q])
                rj[q], uj[q], cj[q], hcj[q] = rr, uu, cc, hc[q]
                hj[q] = (1.0 - uu) * hp[q] + uu * cc


# long: one step of backpropagation through time is read at once (its gates' cotangents in turn)
@njit(cache=True, error_model="numpy")
def gru_backward(offsets, dh_out, wh_t, r, u, c, hsc, hprev, dxs, dhs):
    """Backpropagation through time: given ``dh_out`` (H, columns), the cotangent of each state
    from the decision's own logits, fill the cotangents of the x-parts ``dxs`` and of the h-parts
    ``dhs`` (3H, columns) of every column, from the last step to the first. A state's cotangent is
    its logits' plus the next step's (W_h' dhs + (1 - u) dh, the products first); ``wh_t`` is
    W_h' (H, 3H)."""
    n_h = r.shape[0]
    steps = len(offsets) - 1
    carry = np.zeros((n_h, 0))
    for t in range(steps - 1, -1, -1):
        o, n = offsets[t], offsets[t + 1] - offsets[t]
        dh = np.empty((n_h, n))
        new = np.empty((n_h, n))
        for j in range(n_h):
            d, out = dh[j], dh_out[j, o:o + n]
            for q in range(d.shape[0]):
                d[q] = out[q]
            cj = carry[j]
            for q in range(cj.shape[0]):
                d[q] += cj[q]
            rj, uj, cc_, hcj, hp = r[j, o:o + n], u[j, o:o + n], c[j, o:o + n], \
                hsc[j, o:o + n], hprev[j, o:o + n]
            xr, xu, xc = dxs[j, o:o + n], dxs[n_h + j, o:o + n], dxs[2 * n_h + j, o:o + n]
            sr, su, sc = dhs[j, o:o + n], dhs[n_h + j, o:o + n], dhs[2 * n_h + j, o:o + n]
            nj = new[j]
            for q in range(d.shape[0]):
                g, rr, uu, cc = d[q], rj[q], uj[q], cc_[q]
                dpc = (g * uu) * (1.0 - cc * cc)
                dpr = (dpc * hcj[q]) * (rr * (1.0 - rr))
                dpu = (g * (cc - hp[q])) * (uu * (1.0 - uu))
                xr[q], xu[q], xc[q] = dpr, dpu, dpc
                sr[q], su[q], sc[q] = dpr, dpu, dpc * rr
                nj[q] = g * (1.0 - uu)
        if t > 0:
            # the earlier state's share: W_h' dhs first, then the (1 - u) dh above
            prod = np.zeros((n_h, n))
            _step_products(prod, dhs, o, wh_t)
            for j in range(n_h):
                pj, nj = prod[j], new[j]
                for q in range(pj.shape[0]):
                    nj[q] = pj[q] + nj[q]
        carry = new


# long: one step of the tangent pass is read at once (its gates' changes in turn)
@njit(cache=True, error_model="numpy")
def gru_tangent(offsets, dxs, wh, dwh, r, u, c, hsc, h, hprev, dh):
    """The change ``dh`` (H, columns) of every state along a change of the parameters, given the
    x-parts' change ``dxs`` (3H, columns) and the change ``dwh`` of W_h: forward-mode through the
    gates, each step's h-part change being dW_h h_prev + W_h dh_prev."""
    n_h = wh.shape[1]
    zero = np.zeros(offsets[1] - offsets[0])
    for t in range(len(offsets) - 1):
        o, n = offsets[t], offsets[t + 1] - offsets[t]
        dhs = np.zeros((3 * n_h, n))
        po = offsets[t - 1] if t > 0 else 0
        if t > 0:
            _step_products(dhs, h, po, dwh)
            _step_products(dhs, dh, po, wh)
        for j in range(n_h):
            xr, xu, xc = dxs[j, o:o + n], dxs[n_h + j, o:o + n], dxs[2 * n_h + j, o:o + n]
            sr, su, sc = dhs[j], dhs[n_h + j], dhs[2 * n_h + j]
            rj, uj, cj, hcj = r[j, o:o + n], u[j, o:o + n], c[j, o:o + n], hsc[j, o:o + n]
            hp = hprev[j, o:o + n]
            dhp = dh[j, po:po + n] if t > 0 else zero[:n]
            out = dh[j, o:o + n]
            for q in range(out.shape[0]):
                rr, uu, cc = rj[q], uj[q], cj[q]
                dr = (rr * (1.0 - rr)) * (xr[q] + sr[q])
                du = (uu * (1.0 - uu)) * (xu[q] + su[q])
                dc = (1.0 - cc * cc) * ((xc[q] + dr * hcj[q]) + rr * sc[q])
                out[q] = ((1.0 - uu) * dhp[q] + du * (cc - hp[q])) + uu * dc


# --- the sampler: one decision at a time ------------------------------------------------------

@njit(cache=True, inline="always", error_model="numpy")
def _layer_row(x, n_in, w_t, out):
    """out[j] = sum_i x[i] w_t[i, j] for j < w_t's columns, each sum in input order (four inputs
    per pass along the outputs, which vectorises; every sum still adds its terms one at a time)."""
    n_out = w_t.shape[1]
    for j in range(n_out):
        out[j] = 0.0
    for i in range(n_in):
        xi, wi = x[i], w_t[i]
        for j in range(n_out):
            out[j] += xi * wi[j]


# long: the whole step of one decision (features, gates, logits) is read at once
@njit(cache=True, error_model="numpy")
def step_rows(x, h, feature_w, feature_b, wx_t, b, wh_t, wo_t, bo, logits, h_new):
    """The logits (M, n_actions) and next states ``h_new`` (M, H) of M decisions with inputs ``x``
    (M, in_dim) and states ``h`` (M, H), one row at a time in the training pass's operations.
    Weights transposed, (inputs, outputs), C-contiguous: the feature MLP's ``feature_w`` (biases
    ``feature_b``), the GRU's ``wx_t`` (F, 3H) and ``wh_t`` (H, 3H), the logits' ``wo_t``."""
    n_h = h.shape[1]
    width = x.shape[1]
    for w in feature_w:
        width = max(width, w.shape[1])
    a, y = np.empty(width), np.empty(width)
    xs, hs = np.empty(3 * n_h), np.empty(3 * n_h)
    last = len(feature_w) - 1
    for m in range(x.shape[0]):
        n_in = x.shape[1]
        for i in range(n_in):
            a[i] = x[m, i]
        for k in range(last + 1):
            w, bk = feature_w[k], feature_b[k]
            _layer_row(a, n_in, w, y)
            n_in = w.shape[1]
            for j in range(n_in):
                a[j] = tanh64(y[j] + bk[j]) if k < last else y[j] + bk[j]
        _layer_row(a, n_in, wx_t, xs)
        for j in range(3 * n_h):
            xs[j] = xs[j] + b[j]
        _layer_row(h[m], n_h, wh_t, hs)
        for j in range(n_h):
            rr = sigmoid64(xs[j] + hs[j])
            uu = sigmoid64(xs[n_h + j] + hs[n_h + j])
            cc = tanh64(xs[2 * n_h + j] + rr * hs[2 * n_h + j])
            h_new[m, j] = (1.0 - uu) * h[m, j] + uu * cc
        _layer_row(h_new[m], n_h, wo_t, y)
        for j in range(wo_t.shape[1]):
            logits[m, j] = y[j] + bo[j]
