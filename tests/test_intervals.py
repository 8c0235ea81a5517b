"""Interval kinds, their Monte Carlo coverage, and the claims' switch between t and percentile."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest
from scipy import stats as sps

from repro.claims import intervals_of
from repro.runs.stats import INTERVALS, coverage, expanded_level, interval
from tests.conftest import tree_snapshot, write_result_csv


def normal(n: int, groups: int = 1):
    return lambda rng, m: tuple(rng.normal(size=(m, n)) for _ in range(groups))


def test_t_interval_covers_the_normal_mean_at_its_nominal_level():
    found = coverage(normal(5), 0.0, "mean", ("t",), trials=4000,
                     rng=np.random.default_rng(0))["t"]
    assert abs(found["coverage"] - 0.95) <= 4 * found["coverage_se"]
    assert found["missed_below"] + found["missed_above"] == pytest.approx(1 - found["coverage"])


def test_percentile_bootstrap_of_two_scores_covers_half_the_time():
    # the bootstrap means of two scores are the two scores and their mean: the 95% interval is
    # [min, max], which holds the population median (here the mean) with probability 1/2
    found = coverage(normal(2), 0.0, "mean", ("percentile",), trials=4000, n_boot=400,
                     rng=np.random.default_rng(1))["percentile"]
    assert abs(found["coverage"] - 0.5) <= 4 * found["coverage_se"]


def test_the_calibrated_kinds_cover_more_than_the_percentile_bootstrap_at_five_runs():
    found = coverage(normal(5), 0.0, "mean", INTERVALS, trials=1000, n_boot=500,
                     rng=np.random.default_rng(2))
    assert found["percentile"]["coverage"] < 0.88 < found["expanded"]["coverage"]
    assert found["t"]["coverage"] > 0.92 and found["studentized"]["coverage"] > 0.92


def test_t_intervals_match_their_textbook_forms():
    x = np.array([2.75, 2.77, 2.76, 2.79, 2.70])
    half = sps.t.ppf(0.975, 4) * x.std(ddof=1) / np.sqrt(5)
    assert interval([x]) == pytest.approx((x.mean(), x.mean() - half, x.mean() + half))
    # trimmed mean t (Tukey-McLaughlin): one score trimmed at each end of 5, winsorized sd, 2 df
    w = np.array([2.75, 2.77, 2.76, 2.77, 2.75])
    half = sps.t.ppf(0.975, 2) * w.std(ddof=1) / (0.6 * np.sqrt(5))
    point = np.mean([2.75, 2.76, 2.77])
    assert interval([x], "iqm") == pytest.approx((point, point - half, point + half))
    y = np.array([1.9, 1.7, 2.0, 1.8])
    ci = sps.ttest_ind(x, y, equal_var=False).confidence_interval(0.95)
    assert interval([x, y], "difference")[1:] == pytest.approx((ci.low, ci.high))
    assert interval([np.array([1.0])])[1:] == (-np.inf, np.inf)  # one score: no interval


@pytest.mark.parametrize("statistic", ["mean", "iqm", "difference"])
def test_a_group_of_one_score_has_no_t_interval_and_no_warning(statistic):
    """As a smoke-scale study with one seed meets it: the whole line, quietly."""
    groups = [np.array([1.0]), np.array([1.0, 2.0])][:1 + (statistic == "difference")]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert interval(groups, statistic)[1:] == (-np.inf, np.inf)


def test_the_expanded_level_widens_most_at_few_runs():
    assert expanded_level(5) > expanded_level(10) > 0.95
    assert expanded_level(1000) == pytest.approx(0.95, abs=1e-3)


def test_each_kind_needs_what_it_reads():
    with pytest.raises(ValueError, match="generator"):
        interval([np.arange(5.0)], kind="percentile")


# C8 on constructed data: FS-0.316's stored percentile CI lies just below ED's, while the t CIs
# from the same means and standard errors overlap (as on the 2017-04-22 simulator)
C8_ROWS = [  # simulator, mean, sem, stored percentile CI
    ("ED", 2.798, 0.0073, 2.786, 2.810), ("FS-0.1", 2.798, 0.0073, 2.783, 2.809),
    ("FS-0.316", 2.764, 0.0083, 2.750, 2.778), ("FS-1", 2.777, 0.0144, 2.750, 2.801),
    ("FS-3.16", 2.260, 0.1107, 2.068, 2.452), ("FS-10", 1.593, 0.2375, 1.200, 1.990),
    ("FS-1 (T_health=2.9999)", 1.855, 0.0758, 1.735, 1.998)]


def c8_results(folder, suffix: str) -> None:
    rows = [dict(simulator=s, n_policies=5, mean=m, sem=e, ci_low=lo, ci_high=hi)
            for s, m, e, lo, hi in C8_ROWS]
    write_result_csv(pd.DataFrame(rows), folder / f"transfer{suffix}_summary.csv",
                     finished_utc="2026-11-27T00:00:00Z")


def claim(cid: str):
    from repro.claims import registry

    return next(c for c in registry() if c.id == cid)


def test_c8_reads_pass_with_t_and_partial_with_the_percentile_bootstrap(tmp_path):
    from repro.claims import evaluate_with
    from repro.claims.wildfire import TRANSFER_READINGS

    c8_results(tmp_path, TRANSFER_READINGS[0].suffix)  # the deciding set-up's files
    t, pct = (evaluate_with(claim("C8"), tmp_path, k) for k in ("t", "percentile"))
    assert (t.verdict, t.other) == ("PASS", "percentile: PARTIAL")
    assert (pct.verdict, pct.other) == ("PARTIAL", "t: PASS")
    assert "FS-0.316 (CI below ED's)" in pct.detail and "95% t CIs" in t.detail


def test_x5_reads_with_welch_t_from_the_per_policy_scores(tmp_path):
    from repro.claims import evaluate_with

    # normalisation's difference: stored percentile CI below 0, Welch's t across it
    per_policy = pd.DataFrame(
        [dict(setting=s, simulator=sim, adr_ed=v) for s, sims in (
            ("authors", {"FS-1": [2.78, 2.77, 2.79, 2.80, 2.76],
                         "FS-1 (T_health=2.9999)": [1.8, 1.9, 1.85, 1.7, 2.0]}),
            ("observation normalisation", {"FS-1": [2.90, 2.95, 2.85, 2.92, 2.88],
                                           "FS-1 (T_health=2.9999)": [2.80, 2.95, 2.70, 2.93,
                                                                      2.82]}))
         for sim, vals in sims.items() for v in vals])
    effect = pd.DataFrame([
        dict(setting="authors", n_policies=5, difference=-0.93, ci_low=-1.05, ci_high=-0.79,
             degrades=True, protocol="final policy"),
        dict(setting="observation normalisation", n_policies=5, difference=-0.08, ci_low=-0.15,
             ci_high=-0.01, degrades=True, protocol="final policy")])
    write_result_csv(per_policy, tmp_path / "learner_ablation.csv")
    write_result_csv(effect, tmp_path / "learner_ablation_c9.csv")
    t, pct = (evaluate_with(claim("X5"), tmp_path, k) for k in ("t", "percentile"))
    assert (t.verdict, pct.verdict) == ("FAIL", "PASS")
    assert t.other.startswith("percentile: PASS") and pct.other.startswith("t: FAIL")
    low, ref = (per_policy[(per_policy.setting == "observation normalisation")
                           & (per_policy.simulator == s)].adr_ed for s in
                ("FS-1 (T_health=2.9999)", "FS-1"))
    ci = sps.ttest_ind(low, ref, equal_var=False).confidence_interval(0.95)
    assert f"[{ci.low:+.3f}, {ci.high:+.3f}] with normalisation" in t.ours


def test_the_claims_switch_refuses_an_unknown_interval(tmp_path, monkeypatch, capsys):
    from repro.cli import main

    (tmp_path / "paper").mkdir()
    write_result_csv(pd.DataFrame(dict(x=[1])), tmp_path / "paper" / "table_race.csv")
    monkeypatch.chdir(tmp_path)
    before = tree_snapshot(tmp_path)
    assert main(["claims", "--results-dir", "paper", "--interval", "bca"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "--interval" in err
    assert tree_snapshot(tmp_path) == before


def bus_lambda_results(folder, finals: list[float], thresholds: float, stored: tuple,
                       suffix: str = "_pool") -> None:
    """The lambda sweep's per-epoch table (two epochs, the last one final) and its summary, with
    the percentile CI ``stored`` for the MLP at lambda 2; ``suffix``: the set-up's (C1 is decided
    on the released pool's)."""
    curve = pd.DataFrame([dict(**{"lambda": 2.0}, batch=12000, seed=s, epoch=e,
                               average_return=v if e else 10 * v)
                          for s, v in enumerate(finals) for e in (0, 1)])
    write_result_csv(curve, folder / f"bus_lambda{suffix}.csv",
                     config=dict(epochs=2, final_epochs=1))
    rows = [dict(policy="nohold", runs=1, final_iqm=-1e6), dict(policy="thresholds", runs=1,
                                                                final_iqm=thresholds),
            dict(policy="mlp", **{"lambda": 2.0}, batch=12000, runs=len(finals),
                 final_iqm=float(np.mean(sorted(finals)[1:-1])), ci_low=stored[0],
                 ci_high=stored[1])]
    rows += [dict(policy="mlp-run", **{"lambda": 2.0}, batch=12000, runs=1, final_iqm=v)
             for v in finals]
    write_result_csv(pd.DataFrame(rows), folder / f"bus_lambda{suffix}_summary.csv")


def test_c1_reads_the_trimmed_t_interval_of_the_final_returns(tmp_path):
    from repro.claims import evaluate_with
    from repro.claims.bus import check_c1

    # IQM -100.3; the trimmed t interval, from 2 degrees of freedom, reaches below -101.5
    bus_lambda_results(tmp_path, [-100.0, -101.0, -99.0, -100.0, -300.0], -101.5, (-101.0, -99.3))
    t, pct = (evaluate_with(claim("C1"), tmp_path, k) for k in ("t", "percentile"))
    assert (t.verdict, pct.verdict) == ("PARTIAL", "PASS")
    low = interval([np.array([-100.0, -101.0, -99.0, -100.0, -300.0])], "iqm")[1]
    with intervals_of("t"):
        assert f"[{low:.0f}, " in check_c1(tmp_path, "_pool").ours


def test_c2_bounds_the_spread_by_bonferroni_over_the_lambdas():
    from repro.claims.bus import c2_intervals

    scores = np.array([[-100.0, -90.0], [-101.0, -91.0], [-99.0, -89.0], [-102.0, -88.0],
                       [-98.0, -92.0]])
    with intervals_of("t"):
        spread, gap = c2_intervals(scores, -200.0)
    each = [interval([x], "iqm", confidence=0.975) for x in scores.T]
    assert spread == pytest.approx((10.0, max(0.0, each[1][1] - each[0][2]),
                                    each[1][2] - each[0][1]))
    assert gap == pytest.approx((105.0, (each[0][1] + each[1][1]) / 2 + 200.0,
                                 (each[0][2] + each[1][2]) / 2 + 200.0))


@pytest.mark.slow
def test_the_coverage_study_runs_at_smoke_scale_where_no_scores_can_be_pooled(tmp_path, capsys):
    """`make reproduce SCALE=smoke` runs interval-coverage on studies of 1-2 seeds a setting:
    the smoke scale leaves the suite population out; asked for, it is refused, nothing written."""
    from repro.cli import main

    folders = ["--results-dir", str(tmp_path / "res"), "--figures-dir", str(tmp_path / "fig")]
    assert main(["interval-coverage", "--scale", "smoke", *folders]) == 0
    table = pd.read_csv(tmp_path / "res" / "interval_coverage.csv")
    assert set(table.population) == {"normal", "lognormal", "t3"}
    other = ["--results-dir", str(tmp_path / "res2"), "--figures-dir", str(tmp_path / "fig2")]
    assert main(["interval-coverage", "--scale", "smoke", "--populations", "suite", *other]) == 2
    assert "--populations: must be without suite" in capsys.readouterr().err
    assert not (tmp_path / "res2" / "interval_coverage.csv").exists()
