"""The shared categorical MLP policy, the observation normaliser, and the sampler the engines call.

Parameter sharing (PS-TRPO): every agent of every episode acts with the same network; the agent's
own observation is its only input. Networks are float32 (3-4x faster than float64 on CPU, and what
rllab and stable-baselines use); everything around them (returns, advantages, statistics) is
float64.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import torch
from numba import njit
from torch import nn

from repro.core.rollout import DecisionBatch
from repro.learn.network import affine_chunk
from repro.learn.policy_kernel import depth, logits_into, sample_row, slots, tanh32, width

DTYPE = torch.float32


def mlp(in_dim: int, hidden: Sequence[int], out_dim: int, out_gain: float,
        init: str = "orthogonal") -> nn.Sequential:
    """tanh MLP with zero biases and ``init`` weights: "orthogonal" (gain sqrt 2, the output layer
    ``out_gain``: a small gain makes the initial policy nearly uniform whatever the observation
    scale) or "xavier" (Glorot-uniform, U(-a, a) with a = sqrt(6 / (fan_in + fan_out)), every
    layer; rllab's default for its MLPs). The network's other forms, the derivative products of
    :mod:`repro.learn.network` and the sampler's evaluations below, are checked against one spec of
    it layer by layer (tests/test_policy_network.py)."""
    layers: list[nn.Module] = []
    sizes = [in_dim, *hidden]
    for a, b in zip(sizes[:-1], sizes[1:]):
        layers += [nn.Linear(a, b, dtype=DTYPE), nn.Tanh()]
    layers.append(nn.Linear(sizes[-1], out_dim, dtype=DTYPE))
    for i, layer in enumerate(m for m in layers if isinstance(m, nn.Linear)):
        last = i == len(hidden)
        if init == "xavier":
            nn.init.xavier_uniform_(layer.weight)
        else:
            orthogonal_(layer.weight, gain=out_gain if last else np.sqrt(2.0))
        nn.init.zeros_(layer.bias)
    return nn.Sequential(*layers)


@torch.no_grad()
def orthogonal_(weight: torch.Tensor, gain: float) -> None:
    """``torch.nn.init.orthogonal_`` without LAPACK: the same normal draws from torch's generator,
    the same factor (the Q of the QR decomposition whose R has a positive diagonal, of the draws or
    of their transpose, whichever is tall), computed by modified Gram-Schmidt in float64
    (:func:`_orthonormal_columns`), whose order of operations is fixed; torch's QR runs in MKL,
    whose kernels depend on the CPU's vendor."""
    rows, cols = weight.shape
    draws = weight.new_empty((rows, cols)).normal_(0, 1).numpy().astype(np.float64)
    tall = draws if rows >= cols else draws.T
    q = _orthonormal_columns(np.ascontiguousarray(tall))
    weight.copy_(torch.from_numpy((q if rows >= cols else q.T) * gain))


@njit(cache=True)
def _orthonormal_columns(a):
    """Q of a = QR (``a`` (m, n), m >= n, full column rank), R's diagonal positive."""
    q = a.copy()
    m, n = q.shape
    for j in range(n):
        norm = 0.0
        for i in range(m):
            norm += q[i, j] * q[i, j]
        norm = np.sqrt(norm)
        for i in range(m):
            q[i, j] /= norm
        for k in range(j + 1, n):
            proj = 0.0
            for i in range(m):
                proj += q[i, j] * q[i, k]
            for i in range(m):
                q[i, k] -= proj * q[i, j]
    return q


class ObsNormalizer:
    """Running mean and variance of every observation seen so far (all decisions of all batches).

    Updated only between batches, never within one: the policy that sampled a batch, the one TRPO
    differentiates, and the baseline all see the same normalisation. Needed because raw observations
    mix scales (the bus's headways in minutes with times in seconds). A feature with zero variance
    so far (a constant) maps to 0. Until the first update it is the identity.
    """

    def __init__(self, dim: int, eps: float = 1e-8):
        self.count = 0
        self.mean = np.zeros(dim)
        self.var = np.ones(dim)
        self.eps = eps

    def update(self, x: np.ndarray) -> None:
        """Merge the batch ``x`` (N, dim) into the running moments (Chan et al.'s formula)."""
        n = len(x)
        if n == 0:
            return
        b_mean, b_var = _column_moments(x)
        total = self.count + n
        delta = b_mean - self.mean
        m2 = self.var * self.count + b_var * n + delta**2 * self.count * n / total
        self.mean = self.mean + delta * n / total
        self.var = m2 / total
        self.count = total

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """The batch ``x`` (N, dim) standardised with the current moments."""
        return _standardise(x, self.mean, np.sqrt(self.var + self.eps))

    def state_dict(self) -> dict:
        """Tensors and a number, so that a checkpoint loads with ``weights_only``."""
        return {"count": self.count, "mean": torch.from_numpy(self.mean.copy()),
                "var": torch.from_numpy(self.var.copy())}

    def load_state_dict(self, state: dict) -> None:
        self.count = int(state["count"])
        self.mean, self.var = (torch.as_tensor(state["mean"]).numpy().astype(np.float64),
                               torch.as_tensor(state["var"]).numpy().astype(np.float64))


# The normaliser's passes over a batch, compiled: on a 37,000 x 28 wildfire batch numpy's took 7 ms
# per standardisation (two per epoch) and 11 ms for the moments, for their temporaries, 25 of the
# 140 ms of an epoch's update; these take 1.7 and 1.2 ms and give the same bits.

@njit(cache=True)
def _standardise(x, mean, std):
    """(x - mean) / std, column-wise."""
    out = np.empty_like(x)
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            out[i, j] = (x[i, j] - mean[j]) / std[j]
    return out


@njit(cache=True)
def _column_moments(x):
    """x.mean(axis=0) and x.var(axis=0) of a C-ordered (N >= 1, dim) array, bit for bit: numpy
    sums such an array down its columns one row after another, as these loops do."""
    n, d = x.shape
    total = x[0].copy()
    for i in range(1, n):
        for j in range(d):
            total[j] += x[i, j]
    mean = total / n
    squares = np.zeros(d)
    for i in range(n):
        for j in range(d):
            t = x[i, j] - mean[j]
            squares[j] += t * t
    return mean, squares / n


class CategoricalPolicy(nn.Module):
    """pi(a | o): softmax of an MLP's logits over the environment's discrete macro-actions."""

    def __init__(self, obs_dim: int, n_actions: int, hidden: Sequence[int],
                 init: str = "orthogonal"):
        super().__init__()
        self.net = mlp(obs_dim, hidden, n_actions, out_gain=0.01, init=init)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """Log-probabilities (N, n_actions) of normalised observations."""
        return torch.log_softmax(self.net(obs), dim=-1)


class Sampler:
    """The :data:`~repro.core.rollout.Policy` handed to an engine: for every row of a DecisionBatch,
    a forward pass and inverse-CDF sampling with one uniform from the trainer's Generator, so the
    same generator state gives the same actions.

    Engines call it once per round, often for a handful of rows, where torch's per-operation
    overhead (tens of microseconds) would dominate. So the sampler evaluates a numpy snapshot of the
    network and normaliser, taken when it is created (the policy is fixed during a rollout), in
    compiled loops, float32 like the network: a round of fewer than :data:`BLOCK_MIN` rows row by
    row (:func:`repro.learn.policy_kernel.logits_into`), a larger one :data:`BLOCK` rows side by
    side, feature-major, with the training pass's layer loop
    (:func:`repro.learn.network.affine_chunk`, about twice as fast per row); then each row's
    sampling step (:func:`~repro.learn.policy_kernel.sample_row`). Both evaluations add each sum's
    terms in input order, so the actions are the same bits whichever runs, for rounds of any size
    and on every CPU (tests/test_policy_network.py); numpy's BLAS, whose kernels block their sums
    by CPU, is not used (:mod:`repro.runs.kernels`).
    """

    def __init__(self, policy: CategoricalPolicy, normalizer: ObsNormalizer,
                 rng: np.random.Generator):
        linears = [m for m in policy.net if isinstance(m, nn.Linear)]
        self.weights = tuple(m.weight.detach().numpy().T.copy() for m in linears)
        """Per layer, the (inputs, outputs) weights, float32, C-contiguous: the rows' layout. A
        plain tuple, so that the row loop is compiled for the network's depth
        (:mod:`repro.learn.policy_kernel`)."""
        self.biases = tuple(m.bias.detach().numpy().copy() for m in linears)
        """Per layer, the (outputs,) biases, float32."""
        n, f32 = len(linears), np.float32
        self.layers = slots([m.weight.detach().numpy().copy() for m in linears], n, f32, 2)
        """Per layer, the (outputs, inputs) weights, float32, C-contiguous: the blocks' layout, as
        :func:`slots` (a block's work per layer hides what the runtime depth costs)."""
        self._block_biases = slots(self.biases, n, f32, 1)
        units = max(self.weights[0].shape[0], *(w.shape[0] for w in self.layers))
        self._scratch = np.empty((2, units * BLOCK), np.float32)
        """Two buffers, each as large as a block's widest layer (or its inputs): every call of a
        large round writes them, so one sampler serves one thread at a time (as engines and
        workers call it)."""
        self.mean = normalizer.mean.copy()
        self.scale = 1.0 / np.sqrt(normalizer.var + normalizer.eps)
        self.rng = rng

    def logits(self, obs: np.ndarray) -> np.ndarray:
        """The network's logits (N, n_actions), float32, for raw observations (N, obs_dim)."""
        obs = np.ascontiguousarray(obs, dtype=np.float64)
        if len(obs) < BLOCK_MIN:
            return _logits_rows(obs, self.weights, self.biases, self.mean, self.scale)
        out = np.empty((len(obs), len(self.biases[-1])), np.float32)
        _logits_blocks(obs, self.layers, self._block_biases, self.mean, self.scale, self._scratch,
                       out)
        return out

    def probabilities(self, obs: np.ndarray) -> np.ndarray:
        """pi(. | o) for raw observations (N, obs_dim), in float64."""
        logits = self.logits(obs).astype(np.float64)
        e = np.exp(logits - logits.max(axis=1, keepdims=True))
        return e / e.sum(axis=1, keepdims=True)

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        return self.act(batch, self.rng.random(len(batch.obs)))

    def greedy(self, batch: DecisionBatch) -> np.ndarray:
        """The most probable action of every row (ties: the lowest)."""
        return self.probabilities(batch.obs).argmax(axis=1).astype(np.int64)

    def act(self, batch: DecisionBatch, u: np.ndarray) -> np.ndarray:
        """The actions of ``batch``'s rows, row r's by inverse-CDF sampling with the uniform
        ``u[r]`` (the released pool draws them from each episode's own stream:
        :mod:`repro.learn.pool`)."""
        actions = np.empty(len(batch.obs), np.int64)
        if len(actions) < BLOCK_MIN:
            _act_rows(batch.obs, self.weights, self.biases, self.mean, self.scale, u, actions)
        else:
            _act_blocks(batch.obs, self.layers, self._block_biases, self.mean, self.scale, u,
                        self._scratch, actions)
        return actions


BLOCK = 256
"""Rows a block evaluates side by side (its buffers stay in the first-level cache)."""
BLOCK_MIN = 64
"""The smallest round evaluated in blocks: below it, the blocks' fixed cost per call is more than
what they save (measured on the wildfire's and the bus's networks, both learners')."""


@njit(cache=True, inline="always", error_model="numpy")
def _block_logits(obs, r0, m, layers, biases, mean, scale, scratch):
    """The logits of rows r0 .. r0 + m of ``obs``, feature-major (n_actions, m), in ``scratch``:
    the normalised inputs rounded to float32, then per layer :func:`affine_chunk` (each unit's sum
    in input order, then the bias) and tanh, as :func:`logits_into` computes a row. The layers
    alternate between the two buffers, each viewed as a C-contiguous (units, m) array, the layout
    whose loops LLVM vectorises."""
    d = obs.shape[1]
    src = scratch[0, :d * m].reshape((d, m))
    for i in range(d):
        xi = src[i]
        for c in range(m):
            xi[c] = np.float32((obs[r0 + c, i] - mean[i]) * scale[i])
    last = depth(layers) - 1
    for k in range(last + 1):
        units = layers[k].shape[0]
        dst = scratch[(k + 1) % 2, :units * m].reshape((units, m))
        affine_chunk(dst, src, 0, layers[k], biases[k])
        if k < last:
            for j in range(units):
                out = dst[j]
                for c in range(m):
                    out[c] = tanh32(out[c])
        src = dst
    return src


@njit(cache=True, error_model="numpy")
def _logits_blocks(obs, layers, biases, mean, scale, scratch, out):
    """The logits of every row of ``obs`` into ``out`` (N, n_actions), a block at a time."""
    for r0 in range(0, obs.shape[0], BLOCK):
        m = min(BLOCK, obs.shape[0] - r0)
        out[r0:r0 + m] = _block_logits(obs, r0, m, layers, biases, mean, scale, scratch).T


@njit(cache=True, error_model="numpy")
def _act_blocks(obs, layers, biases, mean, scale, u, scratch, actions):
    """The actions of a round, a block of rows at a time, each row's with its uniform u:
    :func:`_act_rows`'s arithmetic."""
    n_actions = layers[depth(layers) - 1].shape[0]
    row, cdf = np.empty(n_actions, np.float32), np.empty(n_actions)
    for r0 in range(0, obs.shape[0], BLOCK):
        m = min(BLOCK, obs.shape[0] - r0)
        logits = _block_logits(obs, r0, m, layers, biases, mean, scale, scratch)
        for c in range(m):
            for a in range(n_actions):
                row[a] = logits[a, c]
            actions[r0 + c] = sample_row(row, u[r0 + c], cdf)


@njit(cache=True)
def _logits_rows(obs, weights, biases, mean, scale):
    """The logits of every row of ``obs``, row by row (:func:`logits_into`)."""
    n = width(obs.shape[1], weights)
    x, y = np.empty(n, np.float32), np.empty(n, np.float32)
    out = np.empty((obs.shape[0], weights[-1].shape[1]), np.float32)
    for r in range(obs.shape[0]):
        out[r] = logits_into(obs[r], weights, biases, mean, scale, x, y)
    return out


@njit(cache=True)
def _act_rows(obs, weights, biases, mean, scale, u, actions):
    """The actions of a round, row by row with the uniforms u: :func:`act_row`'s arithmetic, with
    its scratch allocated once."""
    n = width(obs.shape[1], weights)
    x, y = np.empty(n, np.float32), np.empty(n, np.float32)
    cdf = np.empty(weights[-1].shape[1])
    for r in range(obs.shape[0]):
        logits = logits_into(obs[r], weights, biases, mean, scale, x, y)
        actions[r] = sample_row(logits, u[r], cdf)
