"""Race-condition study (C10): closed forms, Monte Carlo vs exact, the paper's exponent."""

import numpy as np
import pytest

from repro.core.config import for_scale
from repro.studies.races.race import DISTRIBUTIONS, RaceConfig, run_study
from repro.studies.races.study import (bin_probabilities, largest_safe_dt, no_race_probabilities,
                                       race_probability_exact, race_probability_mc, safe_dt_exact)

EXP = DISTRIBUTIONS["exponential"]


@pytest.fixture(scope="module")
def paper_study():
    # The paper's Monte Carlo settings (10,000 sets, N = 2..20, delta = 0.1); short exact curve.
    cfg = RaceConfig(exact_n=(2, 3, 5, 10, 20, 30, 50))
    return cfg, run_study(cfg, seed=0)


def test_beta_in_paper_range_for_all_distributions(paper_study):
    _, tables = paper_study
    t = tables["table_race"]
    assert set(t.distribution) == {"Exponential", "Chi-Squared", "Gamma"}
    assert t.beta.between(2.1, 2.3).all(), t[["distribution", "beta"]]
    assert (t.beta_se > 0).all() and (t.beta_se < 0.1).all()


def test_two_agents_exponential_has_closed_form():
    # For N = 2 and Exp(1), P(race) = sum_b p_b^2 = (1 - q)/(1 + q) = tanh(dT/2), q = e^-dT.
    for dt in (0.01, 0.2, 1.0, 3.0):
        assert race_probability_exact(EXP, dt, 2) == pytest.approx(np.tanh(dt / 2), rel=1e-9)
    prob = lambda d: race_probability_exact(EXP, d, 2)  # noqa: E731
    expected = 2 * np.arctanh(0.1)
    assert safe_dt_exact(prob, 0.1, 1e-3, 10.0) == pytest.approx(expected, rel=1e-8)
    assert largest_safe_dt(prob, 0.1, 1e-3, 10.0, steps=60) == pytest.approx(expected, rel=1e-8)


def test_bisection_rejects_a_bracket_that_does_not_straddle():
    with pytest.raises(ValueError):
        largest_safe_dt(lambda d: 0.0, 0.1, 1e-3, 1.0, steps=10)


def test_exact_matches_brute_force_elementary_symmetric_polynomial():
    # Direct DP for e_N over the bins, on a coarse grid where it is cheap.
    for key in DISTRIBUTIONS:
        dist, dt, n_max = DISTRIBUTIONS[key], 0.7, 8
        p = np.concatenate(list(bin_probabilities(dist, dt)))
        e = np.zeros(n_max + 1)
        e[0] = 1.0
        for pb in p:
            e[1:] = e[1:] + pb * e[:-1]
        factorial = np.cumprod(np.concatenate([[1.0], np.arange(1, n_max + 1)]))
        np.testing.assert_allclose(no_race_probabilities(dist, dt, n_max), factorial * e,
                                   rtol=1e-9, atol=1e-12)


def test_monte_carlo_agrees_with_exact_within_sampling_error(paper_study):
    cfg, tables = paper_study
    pts = tables["race_dt_vs_n"]
    sigma = np.sqrt(cfg.delta * (1 - cfg.delta) / cfg.n_sets)
    gap = (pts.race_prob_exact - pts.race_prob_mc).abs()
    assert (gap < 4 * sigma).all(), pts.loc[gap.idxmax()]
    assert (pts.race_prob_mc < cfg.delta).all()


def test_mc_race_probability_on_hand_cases():
    times = np.array([[0.1, 0.2, 1.5], [0.1, 1.1, 2.1], [0.9, 0.95, 5.0]])
    assert race_probability_mc(times, 1.0) == pytest.approx(2 / 3)  # rows 1 and 3 race
    assert race_probability_mc(times, 0.03) == 0.0


def test_exact_exponent_tends_to_two(paper_study):
    ranges = paper_study[1]["race_beta_ranges"]
    small, large = ranges[ranges.n_min == 2], ranges[ranges.n_min == 20]
    assert (small.beta.to_numpy() > large.beta.to_numpy()).all()
    assert large.beta.between(1.95, 2.1).all()


def test_scales_change_sizes_only():
    smoke, paper = for_scale(RaceConfig, "smoke"), for_scale(RaceConfig, "paper")
    assert (smoke.delta, smoke.n_min, smoke.n_max) == (paper.delta, paper.n_min, paper.n_max)
    assert paper.n_sets == 10_000


FIT = """
import math
import numpy as np
from repro.studies.races.study import fit_power_law

rng = np.random.default_rng(0)  # its normal draws call no CPU-specific kernel
for n, beta, noise in ((range(20, 301, 20), 2.0163, 1e-3), (range(2, 21), 2.2, 1e-2)):
    dt = [0.5 * math.pow(k, -beta) * math.exp(noise * z) for k, z in zip(n, rng.normal(size=20))]
    print(*map(repr, fit_power_law(np.array(n), np.array(dt[:len(n)]))))
"""


def test_the_power_law_fit_is_statsmodels_ols_in_the_same_bits_on_every_cpu():
    """beta, its standard error and alpha as statsmodels' OLS gives them, and the same bits
    whichever kernels OpenBLAS would pick and with numpy's CPU-specific kernels off (the same
    script through statsmodels gives other last bits under OPENBLAS_CORETYPE=Prescott)."""
    import subprocess
    import sys

    import statsmodels.api as sm

    from repro.studies.races.study import fit_power_law
    from tests.conftest import ROOT, env_without_pins

    rng = np.random.default_rng(3)
    n = np.arange(2, 21)
    dt = 0.6 * n ** -2.2 * np.exp(rng.normal(0, 0.05, len(n)))
    ols = sm.OLS(np.log(dt), sm.add_constant(np.log(n))).fit()
    np.testing.assert_allclose(fit_power_law(n, dt), (-ols.params[1], ols.bse[1],
                                                     np.exp(ols.params[0])), rtol=1e-12)
    assert np.isnan(fit_power_law(n[:2], dt[:2])[1])  # no residual degree of freedom

    def fits(**env: str) -> str:
        done = subprocess.run([sys.executable, "-c", FIT], env=env_without_pins(**env), cwd=ROOT,
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
        return done.stdout

    assert fits() == fits(OPENBLAS_CORETYPE="Prescott", NPY_DISABLE_CPU_FEATURES=(
        "AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL AVX512_SPR"))
