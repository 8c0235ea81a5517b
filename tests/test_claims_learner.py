"""Claims read per learner: the deciding set-up and the others beside it, X5 from the ablation,
and which learner trained a result."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from repro.claims import NOT_RUN, Reading, Verdict, intervals_of, learner_of, side_by_side
from repro.claims.learner import check_x5
from repro.runs.results import read_provenance
from tests.conftest import ROOT, write_result_csv


def test_side_by_side_decides_on_the_first_reading_and_shows_the_others(tmp_path):
    def check(results, suffix):
        frame = pd.read_csv(results / f"x{suffix}.csv")
        return Verdict(f"{frame.v.iloc[0]}", "PASS" if frame.v.iloc[0] > 0 else "FAIL", "d",
                       "paper")

    readings = (Reading("first", "_a"), Reading("second", "_b"))
    checked = side_by_side(check, readings)
    write_result_csv(pd.DataFrame({"v": [-1]}), tmp_path / "x_b.csv")
    v = checked(tmp_path)
    assert v.verdict == NOT_RUN and "first: not yet run" in v.ours and "second: -1 (FAIL)" in v.ours
    write_result_csv(pd.DataFrame({"v": [2]}), tmp_path / "x_a.csv")
    v = checked(tmp_path)
    assert v.verdict == "PASS" and v.scale == "paper"
    assert "**first** (paper scale): PASS" in v.detail
    assert "**second** (paper scale): FAIL" in v.detail


def test_learner_of_reads_the_sidecar_at_any_depth(tmp_path):
    write_result_csv(pd.DataFrame({"a": [1]}), tmp_path / "old.csv", config={"seeds": 5})
    write_result_csv(pd.DataFrame({"a": [1]}), tmp_path / "new.csv",
                     config={"study": {"learner": "authors"}})
    assert learner_of(tmp_path / "old.csv") == "suite"
    assert learner_of(tmp_path / "new.csv") == "authors"


def _c9(tmp_path, norm_high: float) -> None:
    rows = [dict(setting=s, protocol=p, n_policies=5, adr_variant=1.8, adr_fs=2.8,
                 difference=-1.0, ci_low=-1.2, ci_high=hi, degrades=hi < 0)
            for s, hi in (("authors", -0.8), ("observation normalisation", norm_high))
            for p in ("final policy", "last 40 policies")]
    write_result_csv(pd.DataFrame(rows), tmp_path / "learner_ablation_c9.csv")


def test_x5_follows_the_normalised_rows_interval(tmp_path):
    _c9(tmp_path, -0.1)
    with intervals_of("percentile"):  # the stored intervals (t: tests/test_intervals.py)
        assert check_x5(tmp_path).verdict == "PASS"
        _c9(tmp_path, 0.1)
        v = check_x5(tmp_path)
    assert v.verdict == "FAIL" and "Without normalisation it degrades" in v.detail


TRAINED = ("beyond_mgae", "bus_arrivals", "bus_batch", "bus_lambda_suite", "bus_load", "c9_inputs",
           "learner_ablation", "order_reversal", "transfer", "transfer_dt_grid",
           "wildfire_behaviour")
"""Stems of the committed results made of trained policies (a learner's results)."""
UNTRAINED = ("bus_load_switches",)
"""Results among them made without a trained policy."""


def trained_results() -> list[Path]:
    """The committed paper-scale CSVs made of trained policies."""
    paper = Path(__file__).resolve().parents[1] / "results" / "paper"
    return [csv for csv in sorted(paper.rglob("*.csv"))
            if csv.stem.startswith(TRAINED) and csv.stem not in UNTRAINED]


def test_committed_results_name_the_learner_their_sidecars_record():
    """A committed result of trained policies is the suite learner's exactly when its stem says
    ``_suite``: the claims read the two learners' results by name."""
    checked = 0
    for csv in trained_results():
        if "mlp" not in read_provenance(csv).get("policies", ["mlp"]):
            continue  # a bus picture without the trained policy's panel
        suite = "_suite" in csv.stem
        assert learner_of(csv) == ("suite" if suite else "authors"), csv
        checked += 1
    assert checked >= 20


def test_every_result_of_trained_policies_says_which_arithmetic_made_it():
    """Every committed result of trained policies records pinned kernels in its sidecar. Those
    without an ``arithmetic`` were made under the earlier one (torch and MKL's AVX2 branch, which
    regenerates them bit for bit on Intel CPUs only), and docs/performance.md says so exactly while
    any is left."""
    results = trained_results()
    recorded = [read_provenance(csv).get("machine", {}).get("kernels", {}) for csv in results]
    assert [csv.name for csv, k in zip(results, recorded) if not k.get("pinned")] == []
    earlier = [csv.name for csv, k in zip(results, recorded) if "arithmetic" not in k]
    text = (ROOT / "docs" / "performance.md").read_text()
    assert ("made under the earlier one" in text) == bool(earlier)
    assert len(results) >= 20
