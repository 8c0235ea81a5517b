"""Interval estimates across seeds, in the manner of rliable (Agarwal et al., 2021).

The interquartile mean (IQM) is the mean of the middle 50% of the scores; confidence intervals come
from a stratified bootstrap: every group (for example one training simulator or one lambda) is
resampled within itself, so each bootstrap replicate keeps the design's group sizes.

With as few runs as the paper has, percentile intervals are narrower than their nominal level: for
the mean of 5 normal scores a nominal 95% interval covers the true mean 83% of the time. The claims
that compare intervals are therefore decided with t intervals by default
(``repro.claims.INTERVALS``); :func:`intervals` computes every kind the interval-coverage study
compares, and :func:`coverage` measures how often one holds the true value
(``repro/studies/verdicts/interval_coverage.py``).
"""

from __future__ import annotations

from typing import Any, Callable, Sequence

import numpy as np


def iqm(x: np.ndarray, axis: int = -1) -> np.ndarray:
    """Interquartile mean: the 25%-trimmed mean, as rliable computes it (scipy's ``trim_mean``
    drops int(n / 4) whole scores at each end, so with fewer than 4 runs it is the plain mean)."""
    from scipy import stats as sps  # imported where used: the CLI checks options without it

    return sps.trim_mean(np.asarray(x, dtype=float), 0.25, axis=axis)


def bootstrap_ci(scores: np.ndarray, statistic: Callable[[np.ndarray], np.ndarray] = np.mean, *,
                 n_boot: int = 2000, confidence: float = 0.95,
                 rng: np.random.Generator) -> tuple[float, float, float]:
    """Point estimate and percentile bootstrap CI of ``statistic`` over the runs in ``scores``.

    ``scores`` has shape (runs,) or (runs, tasks); with tasks, the runs of each task are resampled
    separately (stratified), and ``statistic`` receives a (runs, tasks) array and reduces it.
    """
    x = np.asarray(scores, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    runs, tasks = x.shape
    point = float(statistic(x.reshape(-1) if tasks == 1 else x))
    idx = rng.integers(0, runs, size=(n_boot, runs, tasks))
    reps = x[idx, np.arange(tasks)]  # (n_boot, runs, tasks), each column resampled within itself
    if tasks == 1:
        boots = np.array([statistic(r.reshape(-1)) for r in reps])
    else:
        boots = np.array([statistic(r) for r in reps])
    lo, hi = np.quantile(boots, [(1 - confidence) / 2, (1 + confidence) / 2])
    return point, float(lo), float(hi)


def sem(x: np.ndarray) -> float:
    """Standard error of the mean (0 for fewer than two values)."""
    x = np.asarray(x, dtype=float)
    return float(x.std(ddof=1) / np.sqrt(len(x))) if len(x) > 1 else 0.0


def ci_side(a: Any, b: Any) -> str:
    """Where the CI of ``a`` lies against that of ``b`` (rows with ci_low and ci_high): "above",
    "below" or "overlapping"."""
    return ("above" if a.ci_low > b.ci_high else "below" if a.ci_high < b.ci_low
            else "overlapping")


INTERVALS = ("t", "percentile", "expanded", "studentized")
"""Interval kinds of :func:`intervals` (the coverage study compares them):

- ``t``: Student's t interval of the mean; of the IQM, the trimmed-mean t of Tukey and McLaughlin
  (winsorized standard error, n - 2g - 1 degrees of freedom for g scores trimmed at each end); of
  a difference of two means, Welch's.
- ``percentile``: the percentile bootstrap, as :func:`bootstrap_ci` (each group resampled within
  itself).
- ``expanded``: the percentile bootstrap read at the wider level of Hesterberg's expanded
  percentile interval, tail alpha'/2 = Phi(-sqrt(n / (n - 1)) t_{n-1, alpha/2}), n the smallest
  group.
- ``studentized``: the bootstrap-t, each resample studentized by the same standard error as ``t``.
"""
STATISTICS = ("mean", "iqm", "difference")
"""Statistics of :func:`intervals`: the mean and the IQM of one group, the difference of the means
of two groups (first minus second)."""


def _trimmed(n: int) -> int:
    """Scores :func:`iqm` drops at each end of n."""
    return int(0.25 * n)


def _winsorized_sd(x: np.ndarray, g: int) -> np.ndarray:
    """Standard deviation (ddof 1) over the last axis after the g smallest and g largest scores
    are set to the nearest kept ones."""
    s = np.sort(x, axis=-1)
    n = s.shape[-1]
    s = np.clip(s, s[..., g:g + 1], s[..., n - g - 1:n - g])
    return s.std(axis=-1, ddof=1)


def estimate(groups: tuple[np.ndarray, ...], statistic: str) -> np.ndarray:
    """``statistic`` of each sample of a batch: ``groups`` holds one array (batch..., n) per
    group."""
    if statistic == "mean":
        return groups[0].mean(axis=-1)
    if statistic == "iqm":
        return iqm(groups[0])
    return groups[0].mean(axis=-1) - groups[1].mean(axis=-1)


def standard_error(groups: tuple[np.ndarray, ...],
                   statistic: str) -> tuple[np.ndarray, np.ndarray]:
    """The standard error of :func:`estimate` and the degrees of freedom of its t interval; where a
    group has one score, there is no spread to estimate: no standard error, no degrees of
    freedom."""
    batch = groups[0].shape[:-1]
    if min(g.shape[-1] for g in groups) < 2:
        return np.full(batch, np.nan), np.zeros(batch)
    if statistic == "difference":
        v = [g.var(axis=-1, ddof=1) / g.shape[-1] for g in groups]
        with np.errstate(invalid="ignore"):  # two resamples without spread: no df, not used
            df = (v[0] + v[1]) ** 2 / sum(vi ** 2 / (g.shape[-1] - 1) for vi, g in zip(v, groups))
        return np.sqrt(v[0] + v[1]), df
    x = groups[0]
    n = x.shape[-1]
    g = _trimmed(n) if statistic == "iqm" else 0
    se = _winsorized_sd(x, g) / ((1 - 2 * g / n) * np.sqrt(n))
    return se, np.full(se.shape, n - 2 * g - 1, dtype=float)


def expanded_level(n: int, confidence: float = 0.95) -> float:
    """The level at which ``expanded`` reads the bootstrap distribution for ``n`` scores."""
    from scipy import stats as sps

    alpha = 1 - confidence
    return float(1 - 2 * sps.norm.cdf(-np.sqrt(n / (n - 1)) * sps.t.ppf(1 - alpha / 2, n - 1)))


def t_limits(point: Any, se: Any, df: Any, confidence: float = 0.95) -> tuple[Any, Any]:
    """Limits of the t interval point +- t_{df, (1 + confidence) / 2} se; without degrees of
    freedom (one score) the interval is the whole line."""
    from scipy import stats as sps

    df = np.asarray(df, dtype=float)
    half = np.where(df >= 1, sps.t.ppf((1 + confidence) / 2, np.maximum(df, 1)) * se, np.inf)
    return point - half, point + half


def interval(groups: Sequence[np.ndarray], statistic: str = "mean", kind: str = "t", *,
             confidence: float = 0.95, n_boot: int = 2000,
             rng: np.random.Generator | None = None) -> tuple[float, float, float]:
    """:func:`intervals` of one sample, ``groups`` its 1-D arrays of scores."""
    point, lo, hi = intervals(tuple(np.asarray(g, dtype=float)[None] for g in groups), statistic,
                              kind, confidence=confidence, n_boot=n_boot, rng=rng)
    return float(point[0]), float(lo[0]), float(hi[0])


def intervals(groups: tuple[np.ndarray, ...], statistic: str, kind: str, *,
              confidence: float = 0.95, n_boot: int = 2000,
              rng: np.random.Generator | None = None) -> tuple[np.ndarray, ...]:
    """Point estimate, lower and upper limit of the ``kind`` interval (:data:`INTERVALS`) of
    ``statistic`` (:data:`STATISTICS`) for every sample of a batch; ``groups`` as
    :func:`estimate`'s. The bootstrap kinds draw ``n_boot`` resamples from ``rng``."""
    point = estimate(groups, statistic)
    alpha = 1 - confidence
    if kind == "t":
        return (point, *t_limits(point, *standard_error(groups, statistic), confidence))
    if rng is None:
        raise ValueError(f"the {kind} interval resamples: it needs a generator")
    reps = tuple(np.take_along_axis(g[..., None, :], rng.integers(
        0, g.shape[-1], size=(*g.shape[:-1], n_boot, g.shape[-1])), axis=-1) for g in groups)
    boots = estimate(reps, statistic)  # (batch..., n_boot)
    if kind in ("percentile", "expanded"):
        level = (confidence if kind == "percentile"
                 else expanded_level(min(g.shape[-1] for g in groups), confidence))
        lo, hi = np.quantile(boots, [(1 - level) / 2, (1 + level) / 2], axis=-1)
        return point, lo, hi
    se, _ = standard_error(groups, statistic)
    se_boot, _ = standard_error(reps, statistic)
    dev = boots - point[..., None]
    # a resample of identical scores has no spread: its t is 0 or beyond any other
    t = np.divide(dev, se_boot, out=np.sign(dev) * 1e300, where=se_boot > 0)
    q_lo, q_hi = np.quantile(t, [alpha / 2, 1 - alpha / 2], axis=-1)
    return point, point - q_hi * se, point - q_lo * se


def coverage(draw: Callable[[np.random.Generator, int], tuple[np.ndarray, ...]], truth: float,
             statistic: str, kinds: tuple[str, ...], *, trials: int, confidence: float = 0.95,
             n_boot: int = 2000, rng: np.random.Generator,
             chunk: int = 250) -> dict[str, dict[str, float]]:
    """Monte Carlo coverage of each interval kind: ``draw(rng, m)`` returns m samples (the groups
    of :func:`intervals`, each (m, n)), and an interval covers when it holds ``truth``, the
    statistic's population value. Every kind sees the same samples (a paired comparison); per
    kind: the share covered, its binomial standard error, the shares missed below (interval
    entirely below ``truth``) and above, and the median width."""
    counts = {k: np.zeros(3) for k in kinds}
    widths: dict[str, list[np.ndarray]] = {k: [] for k in kinds}
    for start in range(0, trials, chunk):
        groups = draw(rng, min(chunk, trials - start))
        for k in kinds:
            _, lo, hi = intervals(groups, statistic, k, confidence=confidence, n_boot=n_boot,
                                  rng=rng)
            counts[k] += [np.sum((lo <= truth) & (truth <= hi)), np.sum(hi < truth),
                          np.sum(lo > truth)]
            widths[k].append(hi - lo)
    out = {}
    for k in kinds:
        covered, below, above = counts[k] / trials
        out[k] = dict(coverage=covered,
                      coverage_se=float(np.sqrt(covered * (1 - covered) / trials)),
                      missed_below=below, missed_above=above,
                      median_width=float(np.median(np.concatenate(widths[k]))))
    return out
