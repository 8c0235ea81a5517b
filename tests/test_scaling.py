"""The scaling driver (C11) at smoke scale: outputs, their consistency, determinism, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from repro.claims import Claim, registry
from repro.cli import main
from tests.conftest import write_result_csv

SMALL = ["--scale", "smoke", "--n-agents", "2", "3", "5", "8", "--duration", "10", "--seed", "5"]


def run_into(tmp: Path, *extra: str) -> Path:
    assert main(["scaling", *SMALL, "--results-dir", str(tmp / "r"),
                 "--figures-dir", str(tmp / "f"), *extra]) == 0
    return tmp / "r"


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    return run_into(tmp_path_factory.mktemp("scaling"))


def test_writes_results_provenance_and_figure(results):
    for name in ("scaling", "scaling_wall", "scaling_fit"):
        assert (results / f"{name}.csv").exists()
        assert (results / f"{name}.provenance.json").exists()
    for ext in ("png", "pdf"):
        assert (results.parent / "f" / f"scaling.{ext}").stat().st_size > 0


def test_work_counts_are_consistent(results):
    work = pd.read_csv(results / "scaling.csv")
    assert sorted(work.n.unique()) == [2, 3, 5, 8]
    ts = work[work.simulator == "time_stepped"].set_index("n")
    fs = work[work.simulator == "rounding_fixed_step"].set_index("n")
    # The same events happen in both (only the order of same-instant events could differ).
    assert (ts.events == fs.events).all() and (ts.tied_events == fs.tied_events).all()
    assert (ts.agent_visits == ts.steps * ts.index).all()
    for row in ts.itertuples():  # one step per grid point t = k dT < duration
        assert row.steps == np.count_nonzero(np.arange(int(row.duration / row.dt) + 2) * row.dt
                                             < row.duration)
    # dT shrinks with N, so steps grow.
    assert np.all(np.diff(ts.dt.to_numpy()) < 0) and np.all(np.diff(ts.steps.to_numpy()) > 0)


def test_fitted_exponents(results):
    fit = pd.read_csv(results / "scaling_fit.csv")
    fit = fit[fit.fit_range == "all"].set_index(["simulator", "measure"])
    steps = fit.loc[("time_stepped", "steps")]
    visits = fit.loc[("time_stepped", "agent_visits")]
    assert 2.0 < steps.exponent < 2.6  # beta over small N is above its large-N limit of 2
    assert visits.exponent == pytest.approx(steps.exponent + 1.0)  # visits = steps x N exactly
    assert 0.6 < fit.loc[("event_driven", "events")].exponent < 1.4
    assert set(fit.index) >= {("event_driven", "wall_seconds"), ("time_stepped", "wall_seconds")}


def test_claim_c11_reads_the_fit(results, tmp_path):
    c11 = next(c for c in registry() if c.id == "C11")
    verdict = c11.evaluate(results)
    assert verdict.verdict == "PASS" and verdict.scale == "smoke"
    assert "wall_seconds" in verdict.detail and "agent_visits" in verdict.detail
    fit = pd.read_csv(results / "scaling_fit.csv")
    fit.loc[fit.measure == "steps", "exponent"] = 1.5  # what a wrong claim would look like
    write_result_csv(fit, tmp_path / "scaling_fit.csv")
    assert c11.evaluate(tmp_path).verdict == "FAIL"
    assert isinstance(c11, Claim) and c11.evaluate(tmp_path / "none").verdict == "not yet run"


def test_work_counts_are_deterministic(results, tmp_path):
    again = run_into(tmp_path, "--no-figure")
    assert (again / "scaling.csv").read_bytes() == (results / "scaling.csv").read_bytes()
    fits = [pd.read_csv(r / "scaling_fit.csv") for r in (results, again)]
    pd.testing.assert_frame_equal(*[f[f.measure != "wall_seconds"] for f in fits])
    other = run_into(tmp_path / "seed", "--no-figure", "--seed", "6")
    assert (other / "scaling.csv").read_bytes() != (results / "scaling.csv").read_bytes()


@pytest.mark.parametrize("bad", [
    ["--n-agents", "1", "2", "3"],
    ["--n-agents", "2", "3"],
    ["--delta", "0"],
    ["--delta", "1.5"],
    ["--distribution", "weibull"],
    ["--scale", "huge"],
])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(bad, tmp_path, capsys):
    rc = main(["scaling", "--results-dir", str(tmp_path / "r"), "--figures-dir",
               str(tmp_path / "f"), *bad])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "error" in err
    assert not any(tmp_path.iterdir())
