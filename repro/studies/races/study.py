"""The race study's mathematics, which the race commands share (``race``, ``wildfire-races``,
``scaling``): the probability that two of N renewal processes' events fall within dT of each
other, by Monte Carlo and exactly, the largest dT that keeps it below delta, and the power law
dT ~ N^-beta; and the names of the result files they share."""

from __future__ import annotations

import math

import numpy as np

from repro.envs.renewal.distributions import Distribution
from repro.runs.progress import progress

RACES, FIT = "races", "races_fit"
"""Stems of the result files of the races in the wildfire simulator (``wildfire-races``: the
per-cell table and the fit), which ``transfer-dt`` reads too."""


def race_probability_mc(sorted_times: np.ndarray, dt: float) -> float:
    """Fraction of sets (rows, each sorted ascending) with two times in one dT bin."""
    bins = np.floor(sorted_times / dt)
    return float(np.mean(np.any(bins[:, 1:] == bins[:, :-1], axis=1)))


def largest_safe_dt(race_prob, delta: float, lo: float, hi: float, steps: int) -> float:
    """Bisection in log dT for the largest dT with race_prob(dT) < delta.

    Requires race_prob(lo) < delta <= race_prob(hi). The race probability is not exactly monotone
    in dT (the grid is anchored at 0), so this returns a crossing point, as the paper's search does.
    """
    if not race_prob(lo) < delta <= race_prob(hi):
        raise ValueError(f"bracket [{lo}, {hi}] does not straddle delta={delta}")
    llo, lhi = np.log(lo), np.log(hi)
    for _ in range(steps):
        mid = 0.5 * (llo + lhi)
        if race_prob(np.exp(mid)) < delta:
            llo = mid
        else:
            lhi = mid
    return float(np.exp(llo))


def safe_dt_exact(race_prob, delta: float, lo: float, hi: float) -> float:
    """The dT at which the exact race probability crosses delta (Brent's method in log dT).

    The exact probability is smooth in dT, so a root finder needs a handful of evaluations where
    bisection would need dozens; each evaluation sums over up to millions of bins.
    """
    from scipy import optimize  # here, not above: the CLI checks options without it

    root = optimize.brentq(lambda x: race_prob(np.exp(x)) - delta, np.log(lo), np.log(hi),
                           xtol=1e-9, rtol=1e-10)
    return float(np.exp(root))


def exact_safe_dts(dist: Distribution, ns: tuple[int, ...], delta: float) -> dict[int, float]:
    """For each N, the dT at which the exact race probability crosses delta.

    dT falls at least as N^-2, so the previous N's answer brackets the next one tightly; brackets
    widen by factors of 4 only, which keeps evaluations away from tiny dT (one costs O(1/dT)).
    """
    out: dict[int, float] = {}
    prev_n, prev_dt = 1, dist.isf(1e-9) * 10  # one bin holds every time: a race for sure
    for n in progress(sorted(ns), f"race exact {dist.name}"):
        prob = lambda d, n=n: race_probability_exact(dist, d, n)  # noqa: E731
        upper = prev_dt * 1.5
        while prob(upper) < delta:
            upper *= 4
        lower = upper * (prev_n / n) ** 3 / 2
        while not prob(lower) < delta:
            lower /= 4
        out[n] = safe_dt_exact(prob, delta, lower, upper)
        prev_n, prev_dt = n, out[n]
    return out


def bin_probabilities(dist: Distribution, dt: float, chunk: int = 1 << 20):
    """Yield the probabilities of consecutive dT bins (in chunks) until the tail is negligible."""
    n_bins = int(np.ceil(dist.isf(1e-17) / dt))
    for start in range(0, n_bins, chunk):
        edges = dt * np.arange(start, min(start + chunk, n_bins) + 1, dtype=float)
        cdf, sf = dist.cdf_sf(edges)
        # Differences of the CDF lose precision near 1; use the survival function there.
        yield np.where(cdf[:-1] < 0.5, np.diff(cdf), -np.diff(sf))


def no_race_probabilities(dist: Distribution, dt: float, n_max: int) -> np.ndarray:
    """G[n] = P(no race among n i.i.d. times) for n = 0..n_max, exactly (see module docstring)."""
    chunks = list(bin_probabilities(dist, dt))
    p_max = max(float(c.max()) for c in chunks)
    # Terms shrink like (n_max p_max)^(k-1): stop once below double precision.
    ratio = min(n_max * p_max, 0.999)
    k_max = n_max if ratio >= 0.5 else min(n_max, int(np.ceil(-40 / np.log(ratio))) + 2)
    power = np.zeros(k_max + 1)
    for c in chunks:
        ck = np.ones_like(c)
        for k in range(1, k_max + 1):
            ck *= c
            power[k] += ck.sum()
    g = np.zeros(n_max + 1)
    g[0] = 1.0
    for n in range(1, n_max + 1):
        falling, total = 1.0, 0.0
        for k in range(1, min(n, k_max) + 1):
            if k > 1:
                falling *= n - k + 1
            total += (-1) ** (k + 1) * power[k] * falling * g[n - k]
        g[n] = total
    return g


def race_probability_exact(dist: Distribution, dt: float, n: int) -> float:
    return float(1.0 - no_race_probabilities(dist, dt, n)[n])


def fit_power_law(n: np.ndarray, dt: np.ndarray) -> tuple[float, float, float]:
    """OLS of log dT = log alpha - beta log N: beta, its standard error (NaN below three points)
    and alpha, as statsmodels' OLS gives them, in arithmetic that is the same on every CPU:
    libm's log and exp of each number and exactly rounded sums (``math.fsum``). Not statsmodels
    itself: it runs in LAPACK, whose kernels OpenBLAS picks by the CPU, on numpy's log, which has
    CPU-specific kernels, so its last bits move with the machine."""
    x = [math.log(v) for v in np.asarray(n, dtype=float).tolist()]
    y = [math.log(v) for v in np.asarray(dt, dtype=float).tolist()]
    m = len(x)
    x_mean, y_mean = math.fsum(x) / m, math.fsum(y) / m
    sxx = math.fsum((a - x_mean) * (a - x_mean) for a in x)
    slope = math.fsum((a - x_mean) * (b - y_mean) for a, b in zip(x, y)) / sxx
    intercept = y_mean - slope * x_mean
    rss = math.fsum((b - intercept - slope * a) * (b - intercept - slope * a)
                    for a, b in zip(x, y))
    se = math.sqrt(rss / (m - 2) / sxx) if m > 2 else math.nan
    return -slope, se, math.exp(intercept)
