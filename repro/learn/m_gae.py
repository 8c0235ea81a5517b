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
every path of a rollout in one compiled loop. :func:`macro_gae` is the public entry point for a
learner of one's own (docs/own-learner.md): the same loop over one path or a time-major batch of
paths (the [steps, envs] layout of Stable-Baselines3 and CleanRL), numpy or torch in and out, its
inputs checked.

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

import math
from typing import Any

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


def macro_gae(rewards: Any, durations: Any, values: Any, last_value: Any, gamma: float,
              lam: float, ends: Any = None) -> tuple[Any, Any]:
    """M-GAE advantages and discounted returns (the baseline's regression target) of one path or
    a batch of paths, for a learner of one's own (docs/own-learner.md).

    - ``rewards[k]``: the reward of macro-action k, discounted within it to its start T_k (what
      the environments' ``step`` hands out); ``durations[k]``: its length dt_k > 0, in the
      environment's time unit; ``values[k]``: the baseline's V(o_k) at its start.
    - One path: 1-D arrays of equal length n and a scalar ``last_value``, V after the last
      decision (0 when the episode ended there).
    - A batch: 2-D arrays of shape [n, m], time-major as Stable-Baselines3's and CleanRL's
      rollouts; column j holds consecutive decisions of one agent, one path after another.
      ``ends[k, j]`` (bool, default all False) says decision k ends its path (its episode ended:
      the value after it is 0, and the next row starts a new path); ``last_value`` (shape [m])
      bootstraps each column's last decision unless that ends its path.
    - ``gamma``: the continuous-time discount rate (per time unit: a reward t later weighs
      exp(-gamma t)); ``lam``: the paper's lambda >= 0, a multiple of that rate (lam > 1 is
      allowed: later residuals weigh less than in the return). With every dt = 1 this is
      standard GAE with gamma_d = exp(-gamma) and gamma_d lambda_d = exp(-gamma lam).

    numpy inputs give float64 arrays; if ``values`` (else ``rewards``) is a torch tensor, both
    results are tensors of its dtype and device. The arithmetic is :func:`m_gae_paths`'s, in
    float64, so a path's results equal the trainer's bit for bit. Bad input raises a one-line
    ValueError naming the argument: zero, negative or non-finite durations, non-finite rewards or
    values, mismatched shapes.
    """
    like = next((x for x in (values, rewards) if _is_tensor(x)), None)
    r, dt, v = _checked(rewards, durations, values, gamma, lam)
    one_path = r.ndim == 1
    r2, dt2, v2 = (x.reshape(len(x), -1) for x in (r, dt, v))
    n, m = r2.shape
    last = _float64(last_value, "last_value").reshape(-1)
    _check(last.shape == (m,), "last_value", "a number" if one_path else f"{m} numbers (one per "
           "column)", f"shape {np.shape(last_value)}")
    _check(np.isfinite(last).all(), "last_value", "finite numbers", "NaN or inf")
    done = np.zeros(r.shape, dtype=bool) if ends is None else np.asarray(
        ends.detach().cpu() if _is_tensor(ends) else ends, dtype=bool)
    _check(done.shape == r.shape, "ends", f"the shape of rewards, {r.shape}",
           f"shape {done.shape}")
    done = done.reshape(n, m)
    # column-major: each column's paths one after another, cut after every ending decision
    cut = done.T.reshape(-1)
    starts = np.flatnonzero(np.concatenate([[True], cut[:-1]]) | (np.arange(n * m) % n == 0))
    path_start = np.append(starts, n * m)
    ends_path = np.append(starts[1:], n * m) - 1  # each path's last decision
    bootstrap = np.where(cut[ends_path], 0.0, last[ends_path // n])
    adv, ret = m_gae_paths(r2.T.reshape(-1), dt2.T.reshape(-1), v2.T.reshape(-1), path_start,
                           gamma, lam, bootstrap)
    adv, ret = (x.reshape(m, n).T.reshape(r.shape) for x in (adv, ret))
    if like is None:
        return adv, ret
    import torch

    return (torch.as_tensor(adv, dtype=like.dtype, device=like.device),
            torch.as_tensor(ret, dtype=like.dtype, device=like.device))


def _checked(rewards: Any, durations: Any, values: Any, gamma: float,
             lam: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`macro_gae`'s path arrays as float64, each input checked (ValueError naming it)."""
    r, dt, v = (_float64(x, name) for x, name in ((rewards, "rewards"),
                                                  (durations, "durations"), (values, "values")))
    _check(r.ndim in (1, 2), "rewards", "a 1-D array (one path) or 2-D [steps, envs]",
           f"shape {r.shape}")
    for x, name in ((dt, "durations"), (v, "values")):
        _check(x.shape == r.shape, name, f"the shape of rewards, {r.shape}", f"shape {x.shape}")
    _check(np.isfinite(r).all(), "rewards", "finite numbers", "NaN or inf")
    _check(np.isfinite(v).all(), "values", "finite numbers", "NaN or inf")
    bad = dt[~(np.isfinite(dt) & (dt > 0))]
    _check(bad.size == 0, "durations", "finite numbers > 0 (each macro-action's length)",
           bad[:1].tolist())
    _check(math.isfinite(gamma) and gamma > 0, "gamma", "a number > 0 (a discount rate)", gamma)
    _check(math.isfinite(lam) and lam >= 0, "lam", "a number >= 0", lam)
    return r, dt, v


def _is_tensor(x: Any) -> bool:
    return type(x).__module__.startswith("torch") and hasattr(x, "detach")


def _float64(x: Any, name: str) -> np.ndarray:
    """``x`` (array-like or torch tensor) as a float64 array; anything else is refused naming
    ``name``."""
    if _is_tensor(x):
        x = x.detach().cpu().double().numpy()
    try:
        return np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be numbers, got {type(x).__name__}") from None


def _check(ok: bool, name: str, allowed: str, got: Any) -> None:
    """A one-line ValueError naming the argument ``name`` unless ``ok``."""
    if not ok:
        raise ValueError(f"{name}: must be {allowed}, got {got}")
