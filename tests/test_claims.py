"""Claim.evaluate: only missing or incomplete result files read "not yet run"; an error in a
check's own code raises, so that a bug is never taken for missing data."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

from repro.claims import NOT_RUN, Claim, Verdict, is_incomplete
from tests.conftest import ROOT, tree_snapshot, write_result_csv


def claim(check) -> Claim:
    return Claim("C0", "a claim", "1.0", "equal", "make nothing", check)


def check_mean(results: Path) -> Verdict:
    """A check that reads column ``x`` of ``table.csv``."""
    from repro.runs.results import read_result

    table = read_result(results / "table.csv")
    return Verdict(f"{table.x.mean():.1f}", "PASS" if table["x"].iloc[0] == 1 else "FAIL")


def test_a_missing_file_reads_not_yet_run(tmp_path):
    assert claim(check_mean).evaluate(tmp_path) == Verdict("-", NOT_RUN, "missing table.csv")


@pytest.mark.parametrize("frame", [pd.DataFrame(dict(y=[1])), pd.DataFrame(dict(x=[]))],
                         ids=["without its column", "without rows"])
def test_an_incomplete_file_reads_not_yet_run(tmp_path, frame):
    write_result_csv(frame, tmp_path / "table.csv")
    v = claim(check_mean).evaluate(tmp_path)
    assert v.verdict == NOT_RUN and "results incomplete" in v.detail, v


def test_a_complete_file_gets_its_verdict(tmp_path):
    write_result_csv(pd.DataFrame(dict(x=[1, 2])), tmp_path / "table.csv")
    assert claim(check_mean).evaluate(tmp_path) == Verdict("1.5", "PASS")


def buggy_attribute(results: Path) -> Verdict:
    v = check_mean(results)
    return Verdict(v.ours.value, v.verdict)  # a str has no .value: a bug in the check


def buggy_key(results: Path) -> Verdict:
    v = check_mean(results)
    return Verdict(v.ours, {"PASS": "PASS"}[v.verdict + "!"])  # a key of the check's own


@pytest.mark.parametrize("check, error", [(buggy_attribute, AttributeError),
                                          (buggy_key, KeyError)])
def test_a_bug_in_a_check_raises(tmp_path, check, error):
    write_result_csv(pd.DataFrame(dict(x=[1, 2])), tmp_path / "table.csv")
    with pytest.raises(error):
        claim(check).evaluate(tmp_path)


def test_only_errors_raised_inside_pandas_or_numpy_count_as_incomplete():
    try:
        pd.DataFrame(dict(x=[1]))["y"]
    except KeyError as err:
        assert is_incomplete(err)
    try:
        {}["y"]
    except KeyError as err:
        assert not is_incomplete(err)
    assert not is_incomplete(KeyError("raised nowhere"))


# --- paper_claims.md from paper-scale results only; a smaller scale's verdicts a smoke check ---

def race_results(folder: Path, scale: str) -> None:
    """C10's result file, as the race driver writes it at ``scale``, passing."""
    folder.mkdir()
    rows = [dict(distribution=d, parameters="", beta=b, beta_se=0.03, alpha=1.0, n_sets=10000,
                 delta=0.1, n_min=2, n_max=20)
            for d, b in (("Exponential", 2.21), ("Chi-Squared", 2.2), ("Gamma", 2.22))]
    write_result_csv(pd.DataFrame(rows), folder / "table_race.csv", scale=scale)


def test_smaller_scales_render_a_smoke_check_beside_their_results(tmp_path, monkeypatch, capsys):
    from repro.cli import main

    race_results(tmp_path / "smoke", "smoke")
    monkeypatch.chdir(tmp_path)
    assert main(["claims", "--results-dir", "smoke"]) == 0
    printed = capsys.readouterr().out
    text = (tmp_path / "smoke" / "claims.md").read_text()
    assert text.startswith("# Smoke check (smoke scale)")
    assert "**A smoke check, not evidence.**" in text and "**A smoke check" in printed
    assert "| C10 |" in printed and "## Details" not in printed  # the table, printed at the end
    assert printed.rstrip().endswith("wrote smoke/claims.md")
    assert not (tmp_path / "paper_claims.md").exists()


def test_paper_claims_md_is_never_rendered_from_a_smaller_scale(tmp_path, monkeypatch, capsys):
    from repro.cli import main

    race_results(tmp_path / "quick", "quick")
    monkeypatch.chdir(tmp_path)
    before = tree_snapshot(tmp_path)
    assert main(["claims", "--results-dir", "quick", "--out", "paper_claims.md"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "error: --out:" in err
    assert "paper-scale results only" in err
    assert tree_snapshot(tmp_path) == before


def test_paper_scale_results_render_paper_claims_md(tmp_path, monkeypatch):
    """The committed paper-scale results, a complete set, render paper_claims.md: the
    checkout's from results/paper, and from a copy elsewhere one beside the copy, leaving the
    checkout's as it was."""
    from repro.cli import main

    shutil.copytree(ROOT / "results" / "paper", tmp_path / "results" / "paper")
    shutil.copytree(ROOT / "results" / "paper", tmp_path / "mine")
    monkeypatch.chdir(tmp_path)
    assert main(["claims"]) == 0
    text = (tmp_path / "paper_claims.md").read_text()
    assert text.startswith("# Paper claims") and "smoke check, not evidence" not in text
    assert "from the paper-scale result CSVs only" in text
    assert not (tmp_path / "results" / "paper" / "claims.md").exists()
    assert main(["claims", "--results-dir", "mine"]) == 0
    assert (tmp_path / "paper_claims.md").read_text() == text
    mine = (tmp_path / "mine" / "paper_claims.md").read_text()
    assert mine.startswith("# Paper claims") and "(results in `mine/`, paper scale)" in mine


def test_an_incomplete_set_of_paper_scale_results_never_renders_paper_claims_md(
        tmp_path, monkeypatch, capsys):
    """One genuine paper-scale result (C10's) is not the paper's claims: its verdicts go to the
    folder's claims.md, and paper_claims.md, asked for by name, is refused, nothing written."""
    from repro.cli import main

    race_results(tmp_path / "paper", "paper")
    (tmp_path / "paper_claims.md").write_text("the evidence\n")
    monkeypatch.chdir(tmp_path)
    before = tree_snapshot(tmp_path)
    assert main(["claims", "--results-dir", "paper", "--out", "paper_claims.md"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "error: --out:" in err
    assert "an incomplete set of paper-scale results (C1, C2" in err
    assert tree_snapshot(tmp_path) == before
    assert main(["claims", "--results-dir", "paper"]) == 0
    assert (tmp_path / "paper_claims.md").read_text() == "the evidence\n"
    text = (tmp_path / "paper" / "claims.md").read_text()
    assert "**Not the evidence.**" in text and "| C10 |" in text


@pytest.mark.parametrize("out", ["paper/table_race.csv", "paper/table_race.provenance.json",
                                 "table.txt"])
def test_claims_out_is_never_a_result_file(tmp_path, monkeypatch, capsys, out):
    from repro.cli import main

    race_results(tmp_path / "paper", "paper")
    monkeypatch.chdir(tmp_path)
    before = tree_snapshot(tmp_path)
    assert main(["claims", "--results-dir", "paper", "--out", out]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "--out: must be a Markdown file name" in err
    assert tree_snapshot(tmp_path) == before


def test_a_claim_decided_on_a_missing_set_up_reads_not_yet_run_with_the_others_beside(tmp_path):
    """decided_on: the deciding set-up's verdict when its results exist; otherwise "not yet run",
    a rerun pending (outdated) where the other readings have results, missing where none do."""
    from repro.claims import NOT_RUN, IncompleteResult, Verdict, decided_on

    def deciding(results):
        if not (results / "deciding.csv").exists():
            raise IncompleteResult("no rows")
        return Verdict("ours", "PASS", "why", "paper")

    beside_present = decided_on(deciding, "the figure's set-up",
                                lambda results: Verdict("other", "FAIL", "other why", "paper"))
    v = beside_present(tmp_path)
    assert (v.verdict, v.outdated) == (NOT_RUN, True) and "other why" in v.detail
    beside_missing = decided_on(deciding, "the figure's set-up",
                                lambda results: Verdict("-", NOT_RUN, "", ""))
    assert not beside_missing(tmp_path).outdated
    (tmp_path / "deciding.csv").write_text("x\n")
    v = beside_present(tmp_path)
    assert v.verdict == "PASS" and v.ours == "ours; other" and "Beside it: other why" in v.detail
