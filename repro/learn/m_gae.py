"""M-GAE: generalized advantage estimation for macro-actions of random durations
(docs/semantics.md section 5.3).

For one agent's path with rewards r_k, durations dt_k and baseline values V_k = V(o_k):

    delta_k = r_k + exp(-gamma dt_k) V_{k+1} - V_k          (V_n = value after the last decision)
    A_k     = sum_l exp(-gamma lam (T_{k+l} - T_k)) delta_{k+l},   T_k = dt_0 + ... + dt_{k-1}
    R_k     = sum_l exp(-gamma (T_{k+l} - T_k)) r_{k+l} + exp(-gamma (T_n - T_k)) V_n

``lam`` is the paper's lambda (:attr:`repro.learn.config.TrainConfig.lam`), which may exceed 1.
R_k (the discounted return-to-go) is the baseline's regression target. With every dt_k = 1 this is
standard GAE with discrete discount gamma_d = e^-gamma and gamma_d lambda_d = e^-(gamma lam), i.e.
lambda_d = e^-(gamma (lam - 1)); in particular lam = 1 gives lambda_d = 1 in both conventions.
(The released implementation discounts the same way: exp(-gamma dt) and exp(-gamma lam dt).)

:func:`m_gae` is the reference for one path, written as the paper's sums over decision times.
:func:`m_gae_paths` is the fast form the trainer uses: the equivalent backward recursions
A_k = delta_k + exp(-gamma lam dt_k) A_{k+1} and R_k = r_k + exp(-gamma dt_k) R_{k+1}, run over
every path of a rollout in one compiled loop.

:func:`advantage_paths` also computes two alternatives that a user of a standard library might
use instead (claim X1, docs/semantics.md section 5.3), with m the batch's mean macro-action
duration:

- ``decision-gae``: every macro-action is one step of standard GAE, with discount
  gamma_d = exp(-gamma m) and gamma_d lambda_d = exp(-gamma lam m) (so lam keeps its meaning):
  M-GAE with every dt_k replaced by m;
- ``duration-gae``: M-GAE's delta_k and R_k (discount exp(-gamma dt_k)), but a lambda weight that
  is constant per decision, lambda_d = exp(-gamma (lam - 1) m):
  A_k = delta_k + exp(-gamma dt_k) lambda_d A_{k+1}. At lam = 1 it is M-GAE.

All three are one recursion with per-decision times tau_k, a rate lam' and a constant c:
discount exp(-gamma tau_k), trace exp(-gamma lam' tau_k) c.
"""

from __future__ import annotations

import numba
import numpy as np


def m_gae(rewards: np.ndarray, durations: np.ndarray, values: np.ndarray, last_value: float,
          gamma: float, lam: float) -> tuple[np.ndarray, np.ndarray]:
    """Advantages and discounted returns of ONE agent's path (see the module docstring).

    ``values[k]`` = V(o_k); ``last_value`` = V after the last decision (0 when the episode ended).
    """
    r = np.asarray(rewards, dtype=float)
    dt = np.asarray(durations, dtype=float)
    v = np.append(np.asarray(values, dtype=float), last_value)
    t = np.concatenate([[0.0], np.cumsum(dt)])  # T_0..T_n
    deltas = r + np.exp(-gamma * dt) * v[1:] - v[:-1]
    elapsed = np.maximum(t[None, :-1] - t[:-1, None], 0.0)  # [k, l] = T_l - T_k for l >= k
    adv = np.triu(np.exp(-gamma * lam * elapsed)) @ deltas
    ret = np.triu(np.exp(-gamma * elapsed)) @ r + np.exp(-gamma * (t[-1] - t[:-1])) * last_value
    return adv, ret


ESTIMATORS = {
    "m-gae": "M-GAE (the paper): discount exp(-gamma dt_k), trace exp(-gamma lam dt_k)",
    "decision-gae": "standard GAE per decision: discount exp(-gamma m), trace exp(-gamma lam m), "
                    "m the batch's mean macro-action duration",
    "duration-gae": "discount exp(-gamma dt_k), trace exp(-gamma dt_k) exp(-gamma (lam - 1) m)",
}
"""The advantage estimators of :func:`advantage_paths`, by name, with what each discounts by."""


@numba.njit(cache=True)
def _gae_kernel(rewards, times, values, path_start, last_values, gamma, lam, trace_factor):
    # every estimator of ESTIMATORS: discount exp(-gamma tau_k), trace exp(-gamma lam tau_k) c; the
    # trace is multiplied by c after the exponential, so that M-GAE's c = 1 changes no bit of
    # exp(-gamma lam tau_k)
    n = rewards.shape[0]
    adv = np.empty(n)
    ret = np.empty(n)
    for p in range(path_start.shape[0] - 1):
        a = 0.0
        g = last_values[p]
        v_next = last_values[p]
        for k in range(path_start[p + 1] - 1, path_start[p] - 1, -1):
            tau = times[k]
            discount = np.exp(-gamma * tau)
            delta = rewards[k] + discount * v_next - values[k]
            a = delta + np.exp(-gamma * lam * tau) * trace_factor * a
            g = rewards[k] + discount * g
            adv[k] = a
            ret[k] = g
            v_next = values[k]
    return adv, ret


def m_gae_paths(rewards: np.ndarray, durations: np.ndarray, values: np.ndarray,
                path_start: np.ndarray, gamma: float, lam: float,
                last_values: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`m_gae` for every path of a rollout at once (decisions of path p are
    ``path_start[p]:path_start[p+1]``); ``last_values`` default to 0 (every path ran to the end of
    its episode)."""
    return advantage_paths("m-gae", rewards, durations, values, path_start, gamma, lam,
                           last_values)


def advantage_paths(estimator: str, rewards: np.ndarray, durations: np.ndarray,
                    values: np.ndarray, path_start: np.ndarray, gamma: float, lam: float,
                    last_values: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Advantages and baseline targets of every path by ``estimator`` (one of :data:`ESTIMATORS`;
    the arguments as :func:`m_gae_paths`). m, the mean macro-action duration of the alternatives,
    is the mean of ``durations``: the trainer passes the whole epoch's batch."""
    durations = np.ascontiguousarray(durations, dtype=np.float64)
    mean = float(durations.mean()) if len(durations) else 0.0
    times, rate, factor = {
        "m-gae": (durations, lam, 1.0),
        "decision-gae": (np.full_like(durations, mean), lam, 1.0),
        "duration-gae": (durations, 1.0, float(np.exp(-gamma * (lam - 1.0) * mean))),
    }[estimator]
    path_start = np.asarray(path_start, dtype=np.int64)
    if last_values is None:
        last_values = np.zeros(len(path_start) - 1)
    return _gae_kernel(np.ascontiguousarray(rewards, dtype=np.float64), times,
                       np.ascontiguousarray(values, dtype=np.float64), path_start,
                       np.ascontiguousarray(last_values, dtype=np.float64), float(gamma),
                       float(rate), factor)
