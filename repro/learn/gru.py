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
into (paths, longest path) arrays, the network runs over all of them at once (the feature MLP in
one product, the GRU one step of every path at a time), and the surrogate, the KL and their
gradients are backpropagated through time. The Fisher-vector product is the released
``FiniteDifferenceHvp(base_eps=1e-5)`` (``gru_fvp = "finite-difference"``: the KL's gradient at
theta + eps v and theta - eps v, eps = base_eps / (|theta| + 1e-8), their difference over 2 eps)
or the exact second derivative by double backward (``"exact"``);
tests/test_learn_gru.py shows the two agree.

Arithmetic: unlike the MLP's compiled loops (:mod:`repro.learn.network`), the GRU runs in torch,
in float64: its matrix products in MKL, pinned at ``MKL_CBWR=COMPATIBLE``, MKL's documented
cross-vendor branch, and torch's elementwise kernels pinned at AVX2 (:mod:`repro.runs.kernels`).
float64 because the finite-difference products perturb the parameters by about 1e-7 of their
norm, a few float32 rounding steps, where float64 leaves their error at about 1e-9 relative.

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
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch
from numba import njit
from torch import nn

from repro.core.rollout import DecisionBatch
from repro.learn.policy import ObsNormalizer, orthogonal_
from repro.learn.policy_kernel import sample_row
from repro.learn.trpo import TRPOStats, conjugate_gradient, dot, line_search

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
        state starting at zero; a shorter path's padding steps are computed and never used."""
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
    evaluates a round's rows in one batched step. Actions by inverse-CDF sampling with one uniform
    per row from the trainer's Generator (:func:`~repro.learn.policy_kernel.sample_row`), as the
    MLP's :class:`~repro.learn.policy.Sampler`; :meth:`greedy` takes the most probable action.
    The policy and normaliser must not change during a rollout."""

    def __init__(self, policy: GRUPolicy, normalizer: ObsNormalizer, rng: np.random.Generator):
        self.policy, self.normalizer, self.rng = policy, normalizer, rng
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
        with torch.no_grad():
            logits, h = self.policy.step(torch.from_numpy(x), torch.from_numpy(self.h[e, a]))
        self.h[e, a] = h.numpy()
        self.count[e, a] += 1
        return logits.numpy()

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


@njit(cache=True)
def _sample_rows(logits, u, actions):
    cdf = np.empty(logits.shape[1])
    for r in range(logits.shape[0]):
        actions[r] = sample_row(logits[r], u[r], cdf)


# --- training ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class Paths:
    """A batch's decisions packed as paths: decision d is step ``t[d]`` of path ``p[d]``."""

    x: torch.Tensor
    """(P, T, obs_dim + n_actions) the network's inputs, zero beyond a path's end."""
    p: torch.Tensor
    t: torch.Tensor

    @staticmethod
    def pack(z: np.ndarray, actions: np.ndarray, path_start: np.ndarray,
             n_actions: int) -> Paths:
        """The paths of a rollout whose normalised observations are ``z`` (D, obs_dim)."""
        lengths = np.diff(path_start)
        p = np.repeat(np.arange(len(lengths)), lengths)
        t = np.arange(len(z)) - np.repeat(path_start[:-1], lengths)
        prev = np.where(t > 0, np.concatenate([[-1], actions[:-1]]), -1)
        x = np.zeros((len(lengths), int(lengths.max(initial=0)), z.shape[1] + n_actions))
        x[p, t] = inputs(z, prev, n_actions)
        return Paths(torch.from_numpy(x), torch.from_numpy(p), torch.from_numpy(t))

    def log_probs(self, policy: GRUPolicy) -> torch.Tensor:
        """log pi(. | decision) (D, n_actions), in decision order."""
        return torch.log_softmax(policy.sequence(self.x)[self.p, self.t], dim=1)


class FlatParameters:
    """A module's parameters as one float64 vector (``parameters_to_vector`` order), for the line
    search (:func:`repro.learn.trpo.line_search`)."""

    def __init__(self, module: nn.Module):
        self.params = list(module.parameters())

    def get_flat(self) -> np.ndarray:
        return nn.utils.parameters_to_vector(self.params).detach().numpy().copy()

    def set_flat(self, theta: np.ndarray) -> None:
        with torch.no_grad():
            nn.utils.vector_to_parameters(torch.from_numpy(np.asarray(theta, np.float64)),
                                          self.params)

    def grad(self, scalar: torch.Tensor, **kw) -> torch.Tensor:
        return torch.cat([g.reshape(-1) for g in torch.autograd.grad(scalar, self.params, **kw)])


def _mean_kl(p_old: torch.Tensor, logp_old: torch.Tensor, logp: torch.Tensor) -> torch.Tensor:
    return (p_old * (logp_old - logp)).sum(dim=1).mean()


def fisher_product(policy: GRUPolicy, paths: Paths, logp_old: torch.Tensor, method: str,
                   base_eps: float, damping: float):
    """v -> (F + damping I) v, F the Hessian of the mean KL(old || current) at the current
    parameters: by ``method`` "exact" (double backward) or "finite-difference" (the released
    ``FiniteDifferenceHvp``, symmetric)."""
    flat = FlatParameters(policy)
    p_old = logp_old.exp()

    def kl_grad(**kw) -> torch.Tensor:
        return flat.grad(_mean_kl(p_old, logp_old, paths.log_probs(policy)), **kw)

    if method == "exact":
        g = kl_grad(create_graph=True)

        def product(v: np.ndarray) -> np.ndarray:
            return flat.grad(g @ torch.from_numpy(v), retain_graph=True).numpy()
    else:
        theta = flat.get_flat()
        eps = base_eps / (math.sqrt(dot(theta, theta)) + 1e-8)

        def product(v: np.ndarray) -> np.ndarray:
            flat.set_flat(theta + eps * v)
            plus = kl_grad()
            flat.set_flat(theta - eps * v)
            minus = kl_grad()
            flat.set_flat(theta)
            return ((plus - minus) / (2 * eps)).numpy()

    return lambda v: product(v) + damping * v


def trpo_step(policy: GRUPolicy, paths: Paths, actions: np.ndarray, adv: np.ndarray, *,
              max_kl: float, cg_iters: int, cg_damping: float, backtrack_ratio: float,
              max_backtracks: int, fvp: str, fvp_eps: float) -> TRPOStats:
    """One constrained update of the gru ``policy`` on a batch packed as ``paths``: the MLP's
    step (:func:`repro.learn.trpo.trpo_step`: conjugate gradient, the same line search), its
    derivatives backpropagated through time. ``adv`` (D,) already normalised."""
    a = torch.from_numpy(np.ascontiguousarray(actions, dtype=np.int64))
    adv_t = torch.from_numpy(np.ascontiguousarray(adv, dtype=np.float64))
    flat = FlatParameters(policy)
    with torch.no_grad():
        logp_old = paths.log_probs(policy)
    rows = torch.arange(len(a))
    entropy = float(-(logp_old.exp() * logp_old).sum(dim=1).mean())
    surr0 = float(adv.mean())

    def surrogate(logp: torch.Tensor) -> torch.Tensor:
        return (torch.exp(logp[rows, a] - logp_old[rows, a]) * adv_t).mean()

    grad = flat.grad(surrogate(paths.log_probs(policy))).numpy()
    fvp_of = fisher_product(policy, paths, logp_old, fvp, fvp_eps, cg_damping)
    direction = conjugate_gradient(fvp_of, grad, cg_iters)
    shs = dot(direction, fvp_of(direction))
    if not shs > 0.0:
        return TRPOStats(0.0, entropy, surr0, surr0, 0, False)
    full_step = np.sqrt(2.0 * max_kl / shs) * direction

    def evaluate() -> tuple[float, float]:
        with torch.no_grad():
            logp = paths.log_probs(policy)
            return (float(surrogate(logp)),
                    float(_mean_kl(logp_old.exp(), logp_old, logp)))

    accepted, backtracks, surr1, kl = line_search(flat, evaluate, full_step, surr0, max_kl,
                                                  backtrack_ratio, max_backtracks)
    return TRPOStats(kl, entropy, surr0, surr1, backtracks, accepted)
