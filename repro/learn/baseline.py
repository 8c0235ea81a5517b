"""Value baselines V(o) that M-GAE subtracts; both are fitted to the latest batch's discounted
returns.

- ``linear`` (default): rllab's LinearFeatureBaseline, which the released implementation used. Per
  decision k of a path the features are [z, z^2, k/100, (k/100)^2, (k/100)^3, 1], z the normalised
  observation clipped to [-10, 10]; ridge regression (coefficient 1e-5, raised tenfold while the
  solve gives NaN, as rllab does). rllab clipped raw observations; this suite feeds it the
  normalised ones, which the clip then leaves alone (the bus's raw times are in the thousands).
- ``mlp``: a tanh MLP regressed by a fixed number of full-batch L-BFGS iterations, warm-started from
  the previous epoch, on targets standardised with the batch's mean and standard deviation.

Both predict 0 before their first fit, so the first batch's advantages are discounted returns.
"""

from __future__ import annotations

import math
from typing import Any, Protocol, Sequence

import numpy as np
import torch
from numba import njit
from torch import nn

from repro.learn.policy import DTYPE, mlp

ROWS = 16
"""Rows of features the normal equations add per pass over the Gram matrix."""
PANEL = 64
"""The row stride of those rows' features, compiled in, for up to PANEL features (obs_dim <= 30)."""
_EPS = float(np.finfo(np.float64).eps)


class Baseline(Protocol):
    def predict(self, obs: np.ndarray, index: np.ndarray) -> np.ndarray:
        """V of normalised observations (N, obs_dim) at decision numbers ``index`` (N,)."""
        ...

    def fit(self, obs: np.ndarray, index: np.ndarray, returns: np.ndarray) -> float:
        """Regress on ``returns``; returns the final mean squared error over their variance."""
        ...

    def state_dict(self) -> dict[str, Any]: ...

    def load_state_dict(self, state: dict[str, Any]) -> None: ...


class LinearFeatureBaseline:
    """rllab's linear feature baseline. BLAS and LAPACK, whose kernels depend on the CPU (numpy's
    OpenBLAS) or its vendor (torch's MKL), are kept out of it (:mod:`repro.runs.kernels`): the
    features, the normal equations, their solve and the prediction are compiled loops whose sums
    run in a fixed order."""

    def __init__(self, obs_dim: int, reg_coeff: float = 1e-5):
        self.coeffs = np.zeros(2 * obs_dim + 4)
        self.reg_coeff = reg_coeff

    @staticmethod
    def features(obs: np.ndarray, index: np.ndarray) -> np.ndarray:
        """The feature matrix (N, 2 obs_dim + 4), row k [z, z^2, k/100, (k/100)^2, (k/100)^3, 1]
        (:func:`_feature_row`), written row by row by a compiled loop."""
        return _features(*_inputs(obs, index))

    def predict(self, obs: np.ndarray, index: np.ndarray) -> np.ndarray:
        """features @ coeffs, one row at a time (the features are never stored)."""
        return _predict(*_inputs(obs, index), self.coeffs)

    def fit(self, obs: np.ndarray, index: np.ndarray, returns: np.ndarray) -> float:
        """Ridge regression: the normal equations X'X + reg I, solved as ``numpy.linalg.lstsq``
        solves them (the minimum-norm solution, singular values below n eps of the largest
        dropped: :func:`_solve_symmetric`), reg raised tenfold while the solution has a NaN. A
        system with a NaN or infinity (from NaN observations or returns) has NaN coefficients."""
        obs, index = _inputs(obs, index)
        gram, rhs = _normal_equations(obs, index, np.ascontiguousarray(returns, np.float64))
        reg = self.reg_coeff
        for _ in range(5):
            system = gram + reg * np.eye(len(gram))
            if not (np.isfinite(system).all() and np.isfinite(rhs).all()):
                coeffs = np.full_like(rhs, np.nan)
            else:
                coeffs = _solve_symmetric(system, rhs)
            if not np.any(np.isnan(coeffs)):
                break
            reg *= 10
        self.coeffs = coeffs
        return _relative_error(_predict(obs, index, self.coeffs), returns)

    def state_dict(self) -> dict[str, Any]:
        return {"coeffs": torch.as_tensor(self.coeffs)}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.coeffs = state["coeffs"].numpy().copy()


class MLPBaseline(nn.Module):
    def __init__(self, obs_dim: int, hidden: Sequence[int], iters: int):
        super().__init__()
        self.net = mlp(obs_dim, hidden, 1, out_gain=1.0)
        self.iters = iters
        self.register_buffer("target_mean", torch.zeros((), dtype=torch.float64))
        self.register_buffer("target_std", torch.ones((), dtype=torch.float64))
        self.register_buffer("fitted", torch.zeros((), dtype=torch.bool))

    def _standardised(self, obs: np.ndarray) -> torch.Tensor:
        return self.net(torch.as_tensor(obs, dtype=DTYPE))[:, 0]

    def predict(self, obs: np.ndarray, index: np.ndarray) -> np.ndarray:
        if not bool(self.fitted):
            return np.zeros(len(obs))
        with torch.no_grad():
            out = self._standardised(obs).double().numpy()
        return float(self.target_mean) + float(self.target_std) * out

    def fit(self, obs: np.ndarray, index: np.ndarray, returns: np.ndarray) -> float:
        self.target_mean = torch.tensor(returns.mean(), dtype=torch.float64)
        self.target_std = torch.tensor(max(returns.std(), 1e-8), dtype=torch.float64)
        target = torch.as_tensor((returns - returns.mean()) / float(self.target_std), dtype=DTYPE)
        x = torch.as_tensor(obs, dtype=DTYPE)
        opt = torch.optim.LBFGS(self.net.parameters(), max_iter=self.iters,
                                line_search_fn="strong_wolfe")

        def closure() -> torch.Tensor:
            opt.zero_grad()
            loss = ((self.net(x)[:, 0] - target) ** 2).mean()
            loss.backward()
            return loss

        opt.step(closure)
        self.fitted = torch.ones((), dtype=torch.bool)
        return _relative_error(self.predict(obs, index), returns)


def _inputs(obs: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return (np.ascontiguousarray(obs, dtype=np.float64),
            np.ascontiguousarray(index, dtype=np.float64))


@njit(cache=True, inline="always")
def _feature_row(obs, k, out):
    """Write [clip(z, -10, 10), its square, k/100, (k/100)^2, (k/100)^3, 1] for the observation
    ``obs`` (z) and decision number ``k`` into ``out``. The clip lets NaN through, as np.clip does;
    (k/100)^3 is libm's pow, as numpy's power computes it at the AVX2 level."""
    d = obs.shape[0]
    for j in range(d):
        z = obs[j]
        if z < -10.0:
            z = -10.0
        elif z > 10.0:
            z = 10.0
        out[j] = z
        out[d + j] = z * z
    t = k / 100.0
    out[2 * d] = t
    out[2 * d + 1] = t * t
    out[2 * d + 2] = math.pow(t, 3.0)
    out[2 * d + 3] = 1.0


@njit(cache=True)
def _normal_equations(obs, index, returns):
    """X'X and X'y of the features X of ``obs`` and ``index``, each entry a sum over the rows in
    batch order (:func:`_add_rows`). The features are padded with zeros to a multiple of 8."""
    width = 2 * obs.shape[1] + 4
    wide = -(-width // 8) * 8
    gram, rhs = np.zeros((wide, wide)), np.zeros(width)
    if wide <= PANEL:  # a row stride LLVM sees as a constant
        _add_rows(obs, index, returns, np.zeros(ROWS * PANEL), PANEL, gram, rhs)
    else:
        _add_rows(obs, index, returns, np.zeros(ROWS * wide), wide, gram, rhs)
    for a in range(width):
        for b in range(a):
            gram[a, b] = gram[b, a]
    return gram[:width, :width].copy(), rhs


@njit(cache=True, inline="always")
def _add_rows(obs, index, returns, block, stride, gram, rhs):
    """Add every row's terms to the upper triangle of X'X (``gram``) and to X'y (``rhs``).

    The order of the work is free as long as each entry's terms are added in batch order (the
    caller mirrors the triangle: f_a f_b and f_b f_a are the same product). :data:`ROWS` rows are
    taken at a time, their features in ``block``, row r at ``r * stride``: an entry adds their
    terms in turn while held in a register (the loop over the rows has a constant length, so LLVM
    unrolls it inside the loop along the Gram matrix's row, which it vectorises), so the matrix is
    loaded and stored once per ROWS rows. Where ``stride`` is a constant (the function is inlined),
    LLVM sees from the rows' constant offsets that its loads cannot overlap the matrix's row;
    otherwise it checks every pair before each pass, which costs more than the pass. Each pass
    along a row of the triangle starts at a multiple of 8 (entries left of the diagonal that this
    also sums are overwritten by the mirror), so that it is whole vectors."""
    n, width = obs.shape[0], len(rhs)
    for n0 in range(0, n, ROWS):
        rows = min(ROWS, n - n0)
        for r in range(rows):
            _feature_row(obs[n0 + r], index[n0 + r], block[r * stride:r * stride + width])
        for a in range(width):
            start = a - a % 8
            row = gram[a, start:]
            if rows == ROWS:
                for b in range(row.shape[0]):
                    total = row[b]
                    col = np.uint64(start + b)
                    for r in range(ROWS):
                        total += block[r * stride + a] * block[np.uint64(r * stride) + col]
                    row[b] = total
            else:
                for r in range(rows):
                    fr, fa = block[r * stride + start:(r + 1) * stride], block[r * stride + a]
                    for b in range(row.shape[0]):
                        row[b] += fa * fr[b]
            for r in range(rows):
                rhs[a] += block[r * stride + a] * returns[n0 + r]


@njit(cache=True)
def _solve_symmetric(a, b):
    """The minimum-norm least-squares solution of a x = b for a symmetric ``a``, as LAPACK's
    gelsd gives it: with a = V diag(lam) V' (cyclic Jacobi rotations, in a fixed order, until
    every off-diagonal entry is negligible), x = sum over |lam_i| > n eps max|lam| of
    v_i (v_i' b) / lam_i, the singular values of a symmetric matrix being its |lam_i|."""
    n = a.shape[0]
    a = a.copy()
    v = np.eye(n)
    for _ in range(100):
        off = 0.0
        for p in range(n):
            for q in range(p + 1, n):
                off += a[p, q] * a[p, q]
        scale = 0.0
        for p in range(n):
            scale += a[p, p] * a[p, p]
        if off <= 1e-32 * scale:
            break
        for p in range(n):
            for q in range(p + 1, n):
                if a[p, q] == 0.0:
                    continue
                theta = (a[q, q] - a[p, p]) / (2.0 * a[p, q])
                t = math.copysign(1.0, theta) / (abs(theta) + math.sqrt(theta * theta + 1.0))
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                for k in range(n):  # columns p and q of a, then rows p and q
                    akp, akq = a[k, p], a[k, q]
                    a[k, p], a[k, q] = c * akp - s * akq, s * akp + c * akq
                for k in range(n):
                    apk, aqk = a[p, k], a[q, k]
                    a[p, k], a[q, k] = c * apk - s * aqk, s * apk + c * aqk
                for k in range(n):
                    vkp, vkq = v[k, p], v[k, q]
                    v[k, p], v[k, q] = c * vkp - s * vkq, s * vkp + c * vkq
    top = 0.0
    for i in range(n):
        top = max(top, abs(a[i, i]))
    cutoff = n * _EPS * top
    x = np.zeros(n)
    for i in range(n):
        if abs(a[i, i]) > cutoff:
            proj = 0.0
            for k in range(n):
                proj += v[k, i] * b[k]
            proj /= a[i, i]
            for k in range(n):
                x[k] += proj * v[k, i]
    return x


@njit(cache=True)
def _features(obs, index):
    x = np.empty((obs.shape[0], 2 * obs.shape[1] + 4))
    for i in range(obs.shape[0]):
        _feature_row(obs[i], index[i], x[i])
    return x


@njit(cache=True)
def _predict(obs, index, coeffs):
    """features @ coeffs, each row's sum in feature order."""
    f = np.empty(len(coeffs))
    out = np.empty(obs.shape[0])
    for i in range(obs.shape[0]):
        _feature_row(obs[i], index[i], f)
        total = 0.0
        for j in range(len(f)):
            total += f[j] * coeffs[j]
        out[i] = total
    return out


def _relative_error(pred: np.ndarray, target: np.ndarray) -> float:
    var = target.var()
    return float(np.mean((pred - target) ** 2) / var) if var > 0 else 0.0


def make_baseline(kind: str, obs_dim: int, hidden: Sequence[int], iters: int) -> Baseline:
    if kind == "linear":
        return LinearFeatureBaseline(obs_dim)
    return MLPBaseline(obs_dim, hidden, iters)
