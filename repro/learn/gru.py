"""The recurrent policy (``TrainConfig.policy = "gru"``): the released bus runner's
``GSMDPCategoricalGRUPolicy`` with its feature network, its sampler, and its TRPO step.

The network (the released ``runners/rurllab.py`` with ``--recurrent gru --feature_net``, the
defaults of ``runners/__init__.py`` and rllab's sandbox ``CategoricalGRUPolicy`` with
``state_include_action=True``): at an agent's decision k the input is its observation and the
one-hot of its own previous action a_{k-1} (zeros at its first decision); a feature MLP (tanh
layers ``gru_features``, 128, 64, 32, then a linear output of ``gru_feature_output``, 16) maps it
to the input of a GRU of ``gru_hidden`` (32) units,

    r = sigmoid(x W_xr + h W_hr + b_r),  u = sigmoid(x W_xu + h W_hu + b_u),
    c = tanh(x W_xc + r * (h W_hc) + b_c),  h' = (1 - u) * h + u * c,

whose state starts at zero at the agent's first decision and runs over that agent's own decisions
in one episode (one path), and a linear layer maps h' to the action logits. Initial weights as
released: Glorot-uniform for the feature MLP, the GRU's input weights (per gate) and the output
layer, orthogonal of gain 1.1 for the GRU's recurrent weights (per gate), zero biases.

Training (PS-TRPO with M-GAE over each agent's decision sequence): the batch's paths are packed
as columns in step-major order (:class:`Paths`), the network runs over all of them at once (the
feature MLP on every decision, the GRU one step of every path still running at a time), and the
surrogate's and the KL's gradients are backpropagated through time. The Fisher-vector product is
the released ``FiniteDifferenceHvp(base_eps=1e-5)`` (``gru_fvp = "finite-difference"``: the KL's
gradient at theta + eps v and theta - eps v, eps = base_eps / (|theta| + 1e-8), their difference
over 2 eps) or the exact J' M J v (``"exact"``: a forward-mode pass through time, the KL's
weighting, a backward pass); tests/test_learn_gru.py shows the two agree.

Arithmetic: as the MLP's (:mod:`repro.learn.network`), compiled loops whose every sum runs in a
fixed order (:mod:`repro.learn.gru_kernel`; the feature MLP is :class:`~repro.learn.network.
TanhMLP`'s), with no library that picks kernels by the CPU: the same bits on every x86-64 CPU
with AVX2 and FMA, Intel or AMD (:mod:`repro.runs.kernels`). tanh and the sigmoid are
:func:`~repro.learn.policy_kernel.tanh64` and :func:`~repro.learn.policy_kernel.sigmoid64`, plain
float64 arithmetic within 2.5 units in the last place; log-softmax and the probabilities use
libm's exp and log, as the MLP's. The sampler evaluates each decision in the training pass's
operations, so the step differentiates the logits the batch was sampled with, bit for bit. torch
keeps the parameters (:class:`GRUPolicy`, which checkpoints save), draws the initial weights, and
is the reference the tests check every compiled product against (:meth:`GRUPolicy.sequence`,
autograd). float64 throughout, because the finite-difference products perturb the parameters by
about 1e-7 of their norm, a few float32 rounding steps, where float64 leaves their error at about
1e-9 relative.

Where it departs from the released policy: the released sampler (``EDhelpers.
ed_simpy_dec_rollout``) builds each agent's policy as ``lambda obs: get_actions_wrapper(agents,
i, ...)`` in a loop over ``i``, and Python binds ``i`` when the lambda is called, after the loop:
every bus acts through the last agent's slot, so while sampling one hidden state and one "previous
action" run over all buses' decisions of an episode in time order, while training (one path per
agent, its recorded ``prev_action``) runs the GRU over each agent's own path from a zero state.
Here the state runs over each agent's own decisions in both, as the paths say it should. The
released recurrent weights are the left singular vectors of uniform draws; these are the
orthogonal factor of normal draws (:func:`repro.learn.policy.orthogonal_`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import torch
from numba import njit
from torch import nn

from repro.core.rollout import DecisionBatch
from repro.learn.gru_kernel import (accumulate_columns, gru_backward, gru_forward, gru_tangent,
                                    kl_gradient_columns, kl_weighting_columns, lane_totals,
                                    linear_columns, products_columns, step_rows, tangent_columns)
from repro.learn.network import LANES, Forward, TanhMLP, log_softmax_into, libm_exp, padded
from repro.learn.policy import ObsNormalizer, orthogonal_
from repro.learn.policy_kernel import sample_row
from repro.learn.trpo import (TRPOStats, conjugate_gradient, dot, line_search, mean_kl_given,
                              score_rows, surrogate_of)

DTYPE = torch.float64
RECURRENT_GAIN = 1.1
"""The gain of the released recurrent weights' orthogonal initialiser."""


class GRUCell(nn.Module):
    """The released GRU step: gates r, u, c stacked in that order in ``x_weight`` (3H, inputs),
    ``h_weight`` (3H, H) and ``bias`` (3H)."""

    def __init__(self, inputs: int, hidden: int):
        super().__init__()
        self.hidden = hidden
        self.x_weight = nn.Parameter(torch.empty(3 * hidden, inputs, dtype=DTYPE))
        self.h_weight = nn.Parameter(torch.empty(3 * hidden, hidden, dtype=DTYPE))
        self.bias = nn.Parameter(torch.zeros(3 * hidden, dtype=DTYPE))
        with torch.no_grad():
            for g in range(3):
                gate = slice(g * hidden, (g + 1) * hidden)
                nn.init.xavier_uniform_(self.x_weight[gate])
                orthogonal_(self.h_weight[gate], RECURRENT_GAIN)

    def forward(self, x: torch.Tensor, h: torch.Tensor) -> torch.Tensor:
        """h' of inputs ``x`` (N, inputs) whose states are ``h`` (N, H)."""
        n = self.hidden
        xs = torch.addmm(self.bias, x, self.x_weight.T)
        hs = h @ self.h_weight.T
        r = torch.sigmoid(xs[:, :n] + hs[:, :n])
        u = torch.sigmoid(xs[:, n:2 * n] + hs[:, n:2 * n])
        c = torch.tanh(xs[:, 2 * n:] + r * hs[:, 2 * n:])
        return (1 - u) * h + u * c


class GRUPolicy(nn.Module):
    """pi(a_k | o_k, a_{k-1}, h_{k-1}): the feature MLP, the GRU and the logit layer."""

    def __init__(self, obs_dim: int, n_actions: int, hidden: int = 32,
                 features: Sequence[int] = (128, 64, 32), feature_output: int = 16):
        super().__init__()
        self.obs_dim, self.n_actions, self.hidden = obs_dim, n_actions, hidden
        layers: list[nn.Module] = []
        sizes = [obs_dim + n_actions, *features, feature_output]
        for a, b in zip(sizes[:-1], sizes[1:]):
            layers += [nn.Linear(a, b, dtype=DTYPE), nn.Tanh()]
        self.features = nn.Sequential(*layers[:-1])  # the output layer is linear
        self.gru = GRUCell(feature_output, hidden)
        self.out = nn.Linear(hidden, n_actions, dtype=DTYPE)
        for m in [*self.features, self.out]:
            if isinstance(m, nn.Linear):
                nn.init.xavier_uniform_(m.weight)
                nn.init.zeros_(m.bias)

    def step(self, x: torch.Tensor, h: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(logits, h') of one decision of each of N agents: inputs ``x`` (N, obs_dim +
        n_actions), states ``h`` (N, H)."""
        h = self.gru(self.features(x), h)
        return self.out(h), h

    def sequence(self, x: torch.Tensor) -> torch.Tensor:
        """Logits (P, T, n_actions) of P paths' inputs ``x`` (P, T, obs_dim + n_actions), every
        state starting at zero; a shorter path's padding steps are computed and never used. The
        torch form of the training pass, which the tests differentiate by autograd as the
        reference of the compiled one (:class:`GRUNet`)."""
        feats = self.features(x)
        h = x.new_zeros((x.shape[0], self.hidden))
        states = []
        for t in range(x.shape[1]):
            h = self.gru(feats[:, t], h)
            states.append(h)
        return self.out(torch.stack(states, dim=1))


def gru_policy(obs_dim: int, n_actions: int, train: dict) -> GRUPolicy:
    """The gru policy of a run's TrainConfig (as a dict: a checkpoint's ``run_config``)."""
    return GRUPolicy(obs_dim, n_actions, train["gru_hidden"], tuple(train["gru_features"]),
                     train["gru_feature_output"])


def inputs(obs: np.ndarray, prev: np.ndarray, n_actions: int) -> np.ndarray:
    """The network's inputs of decisions with (normalised) observations ``obs`` (N, obs_dim) and
    previous actions ``prev`` (N,) (-1: none): the observation, then the previous action one-hot."""
    x = np.zeros((len(obs), obs.shape[1] + n_actions))
    x[:, :obs.shape[1]] = obs
    has = prev >= 0
    x[np.flatnonzero(has), obs.shape[1] + prev[has]] = 1.0
    return x


class GRUSampler:
    """The :data:`~repro.core.rollout.Policy` of a gru policy handed to an engine: it keeps each
    (episode, agent)'s GRU state and previous action across the engine's rounds (zero and none at
    the agent's first decision, ``DecisionBatch.index == 0``, so a new rollout starts afresh), and
    evaluates a round's rows one at a time in the training pass's arithmetic
    (:func:`repro.learn.gru_kernel.step_rows`), so that the step differentiates the logits the
    batch was sampled with and an action does not depend on how the engine groups rows into
    rounds. Actions by inverse-CDF sampling with one uniform per row from the trainer's Generator
    (:func:`~repro.learn.policy_kernel.sample_row`), as the MLP's
    :class:`~repro.learn.policy.Sampler`; :meth:`greedy` takes the most probable action. The
    policy's weights are read when the sampler is made: the policy and normaliser must not change
    during a rollout."""

    def __init__(self, policy: GRUPolicy, normalizer: ObsNormalizer, rng: np.random.Generator):
        self.policy, self.normalizer, self.rng = policy, normalizer, rng
        self.weights = _row_weights(policy)
        self.h = np.zeros((0, 0, policy.hidden))
        """(episodes, agents, H) each agent's state after its last decision."""
        self.prev = np.zeros((0, 0), np.int64)
        """(episodes, agents) each agent's last action."""
        self.count = np.zeros((0, 0), np.int64)
        """(episodes, agents) the decisions each agent has made in this rollout."""

    def _grow(self, batch: DecisionBatch) -> None:
        e, a = int(batch.episode.max()) + 1, int(batch.agent.max()) + 1
        if e > self.h.shape[0] or a > self.h.shape[1]:
            e, a = max(e, self.h.shape[0]), max(a, self.h.shape[1])
            h = np.zeros((e, a, self.h.shape[2]))
            prev, count = np.zeros((e, a), np.int64), np.zeros((e, a), np.int64)
            old = (slice(0, self.h.shape[0]), slice(0, self.h.shape[1]))
            h[old], prev[old], count[old] = self.h, self.prev, self.count
            self.h, self.prev, self.count = h, prev, count

    def _logits(self, batch: DecisionBatch) -> np.ndarray:
        """The logits (M, n_actions) of every row, the agents' states moved on (their previous
        actions are set by :meth:`_commit`)."""
        if len(batch) == 0:
            return np.zeros((0, self.policy.n_actions))
        self._grow(batch)
        e, a = batch.episode, batch.agent
        first = batch.index == 0
        self.h[e[first], a[first]] = 0.0
        self.prev[e[first], a[first]] = -1
        self.count[e[first], a[first]] = 0
        if not (self.count[e, a] == batch.index).all():
            raise ValueError("the engine's decision numbers skip an agent's decision")
        x = inputs(self.normalizer(batch.obs), self.prev[e, a], self.policy.n_actions)
        logits = np.empty((len(batch), self.policy.n_actions))
        h = np.empty((len(batch), self.policy.hidden))
        step_rows(x, np.ascontiguousarray(self.h[e, a]), *self.weights, logits, h)
        self.h[e, a] = h
        self.count[e, a] += 1
        return logits

    def _commit(self, batch: DecisionBatch, actions: np.ndarray) -> np.ndarray:
        self.prev[batch.episode, batch.agent] = actions
        return actions

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        return self.act(batch, self.rng.random(len(batch)))

    def act(self, batch: DecisionBatch, u: np.ndarray) -> np.ndarray:
        """The actions of ``batch``'s rows, row r's by inverse CDF with the uniform ``u[r]``."""
        actions = np.empty(len(batch), np.int64)
        _sample_rows(self._logits(batch), u, actions)
        return self._commit(batch, actions)

    def greedy(self, batch: DecisionBatch) -> np.ndarray:
        """The most probable action of every row (ties: the lowest)."""
        return self._commit(batch, self._logits(batch).argmax(axis=1).astype(np.int64))


def _row_weights(policy: GRUPolicy) -> tuple:
    """The arguments of :func:`~repro.learn.gru_kernel.step_rows` after the inputs and states:
    the weights transposed, (inputs, outputs), C-contiguous, and the biases, float64."""
    def t(w: torch.Tensor) -> np.ndarray:
        return np.ascontiguousarray(w.detach().numpy().T)

    linears = [m for m in policy.features if isinstance(m, nn.Linear)]
    return (tuple(t(m.weight) for m in linears),
            tuple(m.bias.detach().numpy().copy() for m in linears),
            t(policy.gru.x_weight), policy.gru.bias.detach().numpy().copy(),
            t(policy.gru.h_weight), t(policy.out.weight), policy.out.bias.detach().numpy().copy())


@njit(cache=True)
def _sample_rows(logits, u, actions):
    cdf = np.empty(logits.shape[1])
    for r in range(logits.shape[0]):
        actions[r] = sample_row(logits[r], u[r], cdf)


# --- training ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class Paths:
    """A batch's decisions as the compiled pass takes them (:mod:`repro.learn.gru_kernel`):
    columns in step-major order, the paths ranked by decreasing length (ties in path order)."""

    x: np.ndarray
    """(obs_dim + n_actions, padded D) the network's inputs, feature-major, zero beyond D."""
    column: np.ndarray
    """(D,) the column of each decision (in the batch's order)."""
    order: np.ndarray
    """(D,) the decision of each column: ``column[order] == arange(D)``."""
    offsets: np.ndarray
    """(longest path + 1,) step t's columns are ``offsets[t]`` to ``offsets[t + 1]``."""

    @property
    def n(self) -> int:
        return len(self.column)

    @staticmethod
    def pack(z: np.ndarray, actions: np.ndarray, path_start: np.ndarray,
             n_actions: int) -> Paths:
        """The paths of a rollout whose normalised observations are ``z`` (D, obs_dim)."""
        path_start = np.asarray(path_start, np.int64)
        lengths = np.diff(path_start)
        rank = np.empty(len(lengths), np.int64)
        rank[np.argsort(-lengths, kind="stable")] = np.arange(len(lengths))
        running = np.bincount(lengths, minlength=1)[::-1].cumsum()[::-1][1:]  # paths longer than t
        offsets = np.concatenate([[0], np.cumsum(running)]).astype(np.int64)
        p = np.repeat(np.arange(len(lengths)), lengths)
        t = np.arange(len(z)) - np.repeat(path_start[:-1], lengths)
        column = offsets[t] + rank[p]
        order = np.empty(len(z), np.int64)
        order[column] = np.arange(len(z))
        prev = np.where(t > 0, np.concatenate([[-1], actions[:-1]]), -1)
        x = np.zeros((z.shape[1] + n_actions, padded(len(z))))
        x[:, column] = inputs(z, prev, n_actions).T
        return Paths(x, column, order, offsets)


@dataclass
class Pass:
    """The network's pass over a batch (:meth:`GRUNet.forward`), per column, with what the
    derivative products reuse."""

    paths: Paths
    features: Forward
    """The feature MLP's pass; its outputs ``features.logits`` (F, columns) are the GRU's inputs."""
    r: np.ndarray
    u: np.ndarray
    c: np.ndarray
    hsc: np.ndarray
    """W_h h_prev of c's gate (its product with r enters c), (H, columns)."""
    h: np.ndarray
    hprev: np.ndarray
    logits: np.ndarray
    """(n_actions, columns)."""
    _logp: np.ndarray | None = field(default=None, repr=False)
    _probs: np.ndarray | None = field(default=None, repr=False)

    def log_probs(self) -> np.ndarray:
        """log pi(. | decision), (D, n_actions), in column order (computed once)."""
        if self._logp is None:
            self._logp = np.empty((self.paths.n, len(self.logits)))
            log_softmax_into(self.logits, self._logp)
        return self._logp

    def probs(self) -> np.ndarray:
        """exp(log_probs()) by libm's exp, (D, n_actions), in column order (computed once)."""
        if self._probs is None:
            self._probs = libm_exp(self.log_probs())
        return self._probs


class GRUNet:
    """A :class:`GRUPolicy`'s parameters as float64 arrays for the compiled loops
    (:mod:`repro.learn.gru_kernel`), also seen as one flat vector in ``parameters_to_vector``
    order (the feature MLP's, then the GRU's x_weight, h_weight, bias, then the logit layer's).
    The torch module stays the parameters' owner (checkpoints save it): :meth:`set_flat` writes
    both."""

    def __init__(self, policy: GRUPolicy):
        self.policy = policy
        self.features = TanhMLP(policy.features)
        n_h, n_f, n_a = policy.hidden, policy.gru.x_weight.shape[1], policy.n_actions
        self.shapes = ((3 * n_h, n_f), (3 * n_h, n_h), (3 * n_h,), (n_a, n_h), (n_a,))
        self.tensors = (policy.gru.x_weight, policy.gru.h_weight, policy.gru.bias,
                        policy.out.weight, policy.out.bias)
        self.size = self.features.size + sum(math.prod(s) for s in self.shapes)
        self._read()

    def _read(self) -> None:
        with torch.no_grad():
            self.wx, self.wh, self.b, self.wo, self.bo = (t.numpy().copy() for t in self.tensors)
        self.wx_t, self.wh_t, self.wo_t = (np.ascontiguousarray(w.T)
                                           for w in (self.wx, self.wh, self.wo))

    def get_flat(self) -> np.ndarray:
        return np.concatenate([self.features.get_flat(), self.wx.ravel(), self.wh.ravel(), self.b,
                               self.wo.ravel(), self.bo])

    def split(self, v: np.ndarray) -> tuple[np.ndarray, ...]:
        """A flat vector as (the feature MLP's part, W_x, W_h, b, W_o, b_o), float64."""
        v = np.asarray(v, np.float64)
        parts, at = [v[:self.features.size]], self.features.size
        for shape in self.shapes:
            size = math.prod(shape)
            parts.append(np.ascontiguousarray(v[at:at + size].reshape(shape)))
            at += size
        return tuple(parts)

    def set_flat(self, theta: np.ndarray) -> None:
        features, *gru = self.split(theta)
        self.features.set_flat(features)
        with torch.no_grad():
            for tensor, value in zip(self.tensors, gru):
                tensor.copy_(torch.from_numpy(value))
        self._read()

    def forward(self, paths: Paths) -> Pass:
        """The pass over the batch ``paths`` at the current parameters."""
        feats = self.features.forward_columns(paths.x, paths.n)
        cols, n_h = paths.x.shape[1], self.policy.hidden
        xs = np.empty((3 * n_h, cols))
        linear_columns(feats.logits, self.wx, self.b, xs)
        r, u, c, hsc, h, hprev = (_unset((n_h, cols), paths.n) for _ in range(6))
        hprev[:, :paths.offsets[min(1, len(paths.offsets) - 1)]] = 0.0  # before a first step
        gru_forward(paths.offsets, xs, self.wh, r, u, c, hsc, h, hprev)
        logits = np.empty((len(self.bo), cols))
        linear_columns(h, self.wo, self.bo, logits)
        return Pass(paths, feats, r, u, c, hsc, h, hprev, logits)

    def gradient(self, fwd: Pass, g: np.ndarray) -> np.ndarray:
        """J' g: the gradient of sum(g * logits), ``g`` (n_actions, columns) feature-major and
        zero beyond the batch, as a flat vector; backpropagation through time."""
        cols, n_h = g.shape[1], self.policy.hidden
        gw = [np.zeros((*s, LANES)) for s in self.shapes]
        dh_out = np.empty((n_h, cols))
        products_columns(g, self.wo_t, dh_out)
        accumulate_columns(fwd.h, g, gw[3], gw[4])
        dxs, dhs = _unset((3 * n_h, cols), fwd.paths.n), _unset((3 * n_h, cols), fwd.paths.n)
        gru_backward(fwd.paths.offsets, dh_out, self.wh_t, fwd.r, fwd.u, fwd.c, fwd.hsc,
                     fwd.hprev, dxs, dhs)
        accumulate_columns(fwd.features.logits, dxs, gw[0], gw[2])
        accumulate_columns(fwd.hprev, dhs, gw[1], np.zeros((3 * n_h, LANES)))
        df = np.empty((self.wx.shape[1], cols))
        products_columns(dxs, self.wx_t, df)
        out = np.empty(self.size)
        out[:self.features.size] = self.features.vjp_columns(fwd.features, df)
        at = self.features.size
        for lanes in gw:
            size = lanes.size // LANES
            lane_totals(lanes.reshape(size, LANES), out[at:at + size])
            at += size
        return out

    def jvp(self, fwd: Pass, v: np.ndarray) -> np.ndarray:
        """J v: the change of the logits (n_actions, columns) along ``v``, forward mode through
        time."""
        vf, vwx, vwh, vb, vwo, vbo = self.split(v)
        cols, n_h = fwd.logits.shape[1], self.policy.hidden
        df = self.features.jvp_columns(fwd.features, vf)
        dxs = np.empty((3 * n_h, cols))
        tangent_columns(fwd.features.logits, df, self.wx, vwx, vb, dxs)
        dh = _unset((n_h, cols), fwd.paths.n)
        gru_tangent(fwd.paths.offsets, dxs, self.wh, vwh, fwd.r, fwd.u, fwd.c, fwd.hsc, fwd.h,
                    fwd.hprev, dh)
        out = np.empty_like(fwd.logits)
        tangent_columns(fwd.h, dh, self.wo, vwo, vbo, out)
        return out

    def fisher_product(self, fwd: Pass, probs: np.ndarray, v: np.ndarray) -> np.ndarray:
        """J' M J v / D, M = diag(p) - p p' per decision: the Hessian of the mean KL in the
        parameters applied to ``v``. ``probs``: pi(. | decision) feature-major, zero beyond the
        batch (:func:`columns`)."""
        g = np.empty_like(fwd.logits)
        kl_weighting_columns(probs, self.jvp(fwd, v), 1.0 / fwd.paths.n, g)
        return self.gradient(fwd, g)


def _unset(shape: tuple[int, int], n: int) -> np.ndarray:
    """A float64 array for the compiled loops to fill in its first ``n`` columns, zero beyond
    them (the padding's terms weigh 0 in every sum, and must not be NaN)."""
    out = np.empty(shape)
    out[:, n:] = 0.0
    return out


def columns(rows: np.ndarray, width: int) -> np.ndarray:
    """(D, k) per-column rows as a feature-major (k, ``width``) float64 array, zero beyond D."""
    out = np.zeros((rows.shape[1], width))
    out[:, :len(rows)] = rows.T
    return out


def fisher_product(net: GRUNet, fwd: Pass, method: str, base_eps: float,
                   damping: float) -> Callable[[np.ndarray], np.ndarray]:
    """v -> (F + damping I) v, F the Hessian of the mean KL(old || current) at the parameters of
    the pass ``fwd``: by ``method`` "exact" (J' M J v, :meth:`GRUNet.fisher_product`) or
    "finite-difference" (the released ``FiniteDifferenceHvp``, symmetric: the KL's gradient at
    theta + eps v and theta - eps v, eps = base_eps / (|theta| + 1e-8), their difference over
    2 eps)."""
    width, n = fwd.logits.shape[1], fwd.paths.n
    probs_old = fwd.probs()
    if method == "exact":
        probs = columns(probs_old, width)

        def product(v: np.ndarray) -> np.ndarray:
            return net.fisher_product(fwd, probs, v)
    else:
        theta = net.get_flat()
        eps = base_eps / (math.sqrt(dot(theta, theta)) + 1e-8)
        g = np.empty_like(fwd.logits)

        def kl_grad() -> np.ndarray:
            at = net.forward(fwd.paths)
            kl_gradient_columns(at.probs(), probs_old, 1.0 / n, g)
            return net.gradient(at, g)

        def product(v: np.ndarray) -> np.ndarray:
            net.set_flat(theta + eps * v)
            plus = kl_grad()
            net.set_flat(theta - eps * v)
            minus = kl_grad()
            net.set_flat(theta)
            return (plus - minus) / (2 * eps)

    return lambda v: product(v) + damping * v


def trpo_step(policy: GRUPolicy, paths: Paths, actions: np.ndarray, adv: np.ndarray, *,
              max_kl: float, cg_iters: int, cg_damping: float, backtrack_ratio: float,
              max_backtracks: int, fvp: str, fvp_eps: float) -> TRPOStats:
    """One constrained update of the gru ``policy`` on a batch packed as ``paths``: the MLP's
    step (:func:`repro.learn.trpo.trpo_step`: conjugate gradient, the same line search), its
    derivatives backpropagated through time. ``actions`` and ``adv`` (D,) in the batch's order,
    ``adv`` already normalised; every sum over decisions runs in column order."""
    net = GRUNet(policy)
    a = np.ascontiguousarray(np.asarray(actions, np.int64)[paths.order])
    adv_c = np.ascontiguousarray(np.asarray(adv, np.float64)[paths.order])
    fwd = net.forward(paths)
    logp_old, probs_old = fwd.log_probs(), fwd.probs()
    entropy = -mean_kl_given(probs_old, logp_old, np.zeros_like(logp_old))
    surr0 = float(adv.mean())  # every ratio is 1 at theta_old
    grad = net.gradient(fwd, columns(score_rows(probs_old, a, adv_c), fwd.logits.shape[1]))
    fvp_of = fisher_product(net, fwd, fvp, fvp_eps, cg_damping)
    direction = conjugate_gradient(fvp_of, grad, cg_iters)
    shs = dot(direction, fvp_of(direction))
    if not shs > 0.0:
        return TRPOStats(0.0, entropy, surr0, surr0, 0, False)
    full_step = np.sqrt(2.0 * max_kl / shs) * direction

    def evaluate() -> tuple[float, float]:
        logp = net.forward(paths).log_probs()
        return surrogate_of(logp, logp_old, a, adv_c), mean_kl_given(probs_old, logp_old, logp)

    accepted, backtracks, surr1, kl = line_search(net, evaluate, full_step, surr0, max_kl,
                                                  backtrack_ratio, max_backtracks)
    return TRPOStats(kl, entropy, surr0, surr1, backtracks, accepted)
