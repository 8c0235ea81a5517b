"""The bus training sweeps end to end at smoke scale: outputs, orderings a short run can show,
resumption with byte-identical CSVs, the trained-MLP figure panels, the claim checks, bad input."""

from __future__ import annotations

import subprocess
import sys

import pandas as pd
import pytest

from repro.claims import VERDICTS
from repro.claims.bus import check_c1, check_c2, check_c3, check_c5
from repro.cli import main


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory):
    res, fig, runs = (tmp_path_factory.mktemp(n) for n in ("res", "fig", "runs"))
    common = ["--scale", "smoke", "--results-dir", str(res), "--figures-dir", str(fig)]
    sweep = [*common, "--runs-dir", str(runs), "--n-jobs", "1", "--seeds", "1"]
    assert main(["bus-thresholds", "--scale", "smoke", "--results-dir", str(res)]) == 0
    assert main(["fig-bus-lambda", *sweep]) == 0
    assert main(["fig-bus-batch", *sweep]) == 0
    for cmd in ("fig-bus-arrivals", "fig-bus-load"):
        assert main([cmd, *common]) == 0
    return res, fig, sweep


def test_outputs(sweeps):
    res, fig, _ = sweeps
    table = pd.read_csv(res / "bus_lambda.csv")
    assert list(table.columns) == ["lambda", "batch", "seed", "epoch", "average_return",
                                   "average_discounted_return"]
    assert sorted(table["lambda"].unique()) == [0.5, 1.0, 2.0, 4.0]
    assert sorted(pd.read_csv(res / "bus_batch.csv").batch.unique()) == [6, 12, 24]
    for stem in ("bus_lambda", "bus_batch"):
        assert (fig / f"{stem}.png").exists() and (fig / f"{stem}.pdf").exists()
        assert (res / f"{stem}_summary.provenance.json").exists()
    assert set(pd.read_csv(res / "bus_arrivals.csv").policy) == {"nohold", "mlp", "thresholds"}
    assert set(pd.read_csv(res / "bus_load.csv").policy) == {"nohold", "mlp", "thresholds"}


def test_orderings_a_short_run_shows(sweeps):
    """Optimized Thresholds above No Holding; the trained policy above No Holding and above where
    it started (a random policy already edges No Holding, so that alone would prove nothing)."""
    res = sweeps[0]
    summary = pd.read_csv(res / "bus_lambda_summary.csv")
    base = summary.set_index("policy").final_iqm
    assert base["thresholds"] > base["nohold"]
    curve = pd.read_csv(res / "bus_lambda.csv").query("`lambda` == 2.0")
    mlp = summary[(summary.policy == "mlp") & (summary["lambda"] == 2.0)].final_iqm.iloc[0]
    assert mlp > base["nohold"]
    assert curve.average_return.iloc[-1] > curve.average_return.iloc[0]


def test_rerun_skips_finished_runs_and_rewrites_identically(sweeps):
    res, _, sweep = sweeps
    before = (res / "bus_batch.csv").read_bytes()
    assert main(["fig-bus-batch", *sweep]) == 0
    assert (res / "bus_batch.csv").read_bytes() == before


def test_claim_checks_give_verdicts(sweeps):
    res = sweeps[0]
    for check in (check_c1, check_c2, check_c3, check_c5):
        v = check(res)
        assert v.verdict in VERDICTS and v.scale == "smoke" and v.ours


@pytest.mark.parametrize("args", [
    ["fig-bus-lambda", "--seeds", "0"],
    ["fig-bus-batch", "--epochs", "2", "--final-epochs", "3"],
    ["fig-bus-lambda", "--n-jobs", "0"],
    ["fig-bus-lambda"],  # no results/bus_thresholds.csv yet
    ["fig-bus-arrivals", "--policies", "mlp"],  # no lambda sweep yet
])
def test_bad_input(args, tmp_path):
    proc = subprocess.run([sys.executable, "-m", "repro", *args, "--scale", "smoke",
                           "--results-dir", str(tmp_path / "r"), "--figures-dir",
                           str(tmp_path / "f"), *(["--runs-dir", str(tmp_path / "runs")]
                                                  if "arrivals" not in args[0] else [])],
                          capture_output=True, text=True)
    assert proc.returncode == 2, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())
