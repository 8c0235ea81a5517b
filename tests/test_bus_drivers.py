"""The bus command-line drivers: outputs, determinism, one-line errors that write nothing."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from repro.claims.bus import check_c4, load_distances
from repro.cli import main

pytestmark = pytest.mark.slow  # studies end to end, subprocesses: left out of make test-fast


def _repro(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "repro", *args], capture_output=True, text=True,
                          cwd=cwd)


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    res, fig = tmp_path_factory.mktemp("res"), tmp_path_factory.mktemp("fig")
    common = ["--scale", "smoke", "--results-dir", str(res)]
    assert main(["bus-thresholds", *common]) == 0
    for cmd in ("fig-bus-load", "fig-bus-arrivals"):
        # the trained-MLP panel is tested with the training sweeps (tests/test_bus_sweeps.py)
        assert main([cmd, *common, "--figures-dir", str(fig), "--policies", "nohold",
                     "authors", "thresholds"]) == 0
    return res, fig


def test_outputs_and_c4(smoke):
    res, fig = smoke
    table = pd.read_csv(res / "bus_thresholds.csv").set_index("source")
    t = table.loc["ours"]
    assert t.T1 > t.T2 > t.T3 and t.evaluations > 0
    np.testing.assert_allclose(table.loc["authors", ["T1", "T2", "T3"]].to_numpy(float),
                               [532.79107018, 340.28721132, 262.62855417], rtol=1e-9)
    assert (res / "bus_thresholds.provenance.json").exists()
    assert (fig / "bus_load.png").exists() and (fig / "bus_arrivals.pdf").exists()
    assert set(pd.read_csv(res / "bus_arrivals.csv").policy) == {"nohold", "authors",
                                                                 "thresholds"}
    assert check_c4(res).verdict == "PASS"


def test_load_figure_reproduces_the_paper(smoke):
    """With No Holding and with the authors' thresholds our loads equal the paper's at all 55 points
    of each panel (docs/semantics.md section 6.5); the file holds both sources side by side."""
    res, _ = smoke
    table = pd.read_csv(res / "bus_load.csv")
    assert list(table.columns) == ["source", "policy", "bus", "record", "stop", "load"]
    paper = table[table.source == "paper"]
    assert len(paper[paper.policy == "authors"]) == 55
    dist = load_distances(table)
    assert dist["nohold"] == 0.0 and dist["authors"] == 0.0
    ours = table[(table.source == "ours") & (table.policy == "authors")]
    assert sorted(ours.bus.unique()) == [1, 2, 3, 4, 5, 6]  # Bus 6 too, for --all-buses
    off = pd.read_csv(res / "bus_load_switches.csv").set_index(["policy", "off"]).l1_per_point
    assert off["authors", "none"] == 0.0 and off["authors", "b3_boarding"] > 1.0
    assert off["authors", "all"] > 1.0 and (off["nohold"] == 0.0).all()


def test_load_figure_fails_on_the_corrected_semantics(tmp_path):
    """The comparison can fail: the paper's prose (--corrected) does not draw its thresholds
    panel."""
    assert main(["fig-bus-load", "--results-dir", str(tmp_path), "--figures-dir",
                 str(tmp_path / "fig"), "--policies", "authors", "--corrected"]) == 0
    assert load_distances(pd.read_csv(tmp_path / "corrected" / "bus_load.csv"))["authors"] > 1.0


def test_each_semantics_writes_a_folder_of_its_own_at_its_scale(tmp_path):
    """The bus writes the same file names for every semantics: a corrected or switched run writes
    into the subfolder named for its semantics, at the scale asked (they choose the study, not
    its settings), and leaves the released results beside it as they were."""
    res, fig = tmp_path / "res", tmp_path / "fig"
    common = ["fig-bus-load", "--scale", "paper", "--results-dir", str(res), "--figures-dir",
              str(fig), "--policies", "nohold", "authors"]
    assert main(common) == 0
    released = {p: p.read_bytes() for p in res.iterdir() if p.is_file()}
    for switches, folder in ((["--corrected"], "corrected"),
                             (["--no-b1-reward"], "b2-b3-b4-b5")):
        assert main([*common, *switches]) == 0
        side = json.loads((res / folder / "bus_load.provenance.json").read_text())
        assert side["scale"] == "paper" and (fig / folder / "bus_load.png").exists()
        assert {p: p.read_bytes() for p in res.iterdir() if p.is_file()} == released
    theirs = pd.read_csv(res / "corrected" / "bus_load.csv")
    assert not theirs.equals(pd.read_csv(res / "bus_load.csv"))


def test_thresholds_deterministic(smoke, tmp_path):
    res, _ = smoke
    assert main(["bus-thresholds", "--scale", "smoke", "--results-dir", str(tmp_path)]) == 0
    assert ((tmp_path / "bus_thresholds.csv").read_bytes()
            == (res / "bus_thresholds.csv").read_bytes())


def test_eval_json(smoke, capsys):
    res, _ = smoke
    assert main(["bus-eval", "--policy", "nohold", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["loads_records_40_50"][0] == [50, 64, 60, 75, 75, 75, 75, 75, 75, 75, 50]
    assert {"return", "discounted_return", "time_to_regularity_min"} <= set(out)
    assert main(["bus-eval", "--policy", "thresholds", "--results-dir", str(res), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["return"] > out["return"]


@pytest.mark.parametrize("args, param", [
    (["bus-eval", "--policy", "thresholds", "--thresholds", "300", "-5", "100"], "--thresholds"),
    (["bus-eval", "--policy", "mystery"], "--policy"),
    (["fig-bus-load", "--policies", "nohold", "thresholds", "--thresholds", "6", "inf", "1"],
     "--thresholds"),
    (["fig-bus-load", "--policies", "nohold", "mystery"], "--policies"),
    (["fig-bus-arrivals", "--policies", "mystery"], "--policies"),
    (["bus-eval", "--policy", "nohold", "--thresholds", "6", "4", "2"], "--thresholds"),
    (["bus-eval", "--policy", "thresholds", "--mlp-run", "runs/x"], "--mlp-run"),
])
def test_bad_input(args, param, tmp_path):
    # the figures write into --results-dir; bus-eval writes nothing, and refuses a --results-dir
    # its policy does not read
    folders = [] if args[0] == "bus-eval" else ["--results-dir", str(tmp_path / "r")]
    proc = _repro(*args, *folders)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and f"error: {param}:" in lines[0], proc.stderr
    assert not (tmp_path / "r").exists()


def test_mlp_run_of_another_environment_is_refused(tmp_path):
    """Refused in one line, nothing written: run in a folder of its own, whose only entry is the
    toy run (the default figures folder, figures/quick, is relative to it)."""
    run = tmp_path / "toy"
    assert main(["train", "--env", "toy", "--scale", "smoke", "--out", str(run)]) == 0
    results = ["--results-dir", str(tmp_path / "r")]
    for cmd in (["bus-eval", "--policy", "mlp"], ["fig-bus-load", "--policies", "mlp", *results],
                ["fig-bus-load", "--policies", "mlp", *results, "--figures-dir",
                 str(tmp_path / "f")]):
        proc = _repro(*cmd, "--mlp-run", str(run), cwd=tmp_path)
        assert proc.returncode == 2 and "error: --mlp-run: must be the checkpoint.pt of a bus" \
            in proc.stderr, proc.stderr
        assert list(tmp_path.iterdir()) == [run], cmd


def test_missing_thresholds_file(tmp_path):
    proc = _repro("bus-eval", "--policy", "thresholds", "--results-dir", str(tmp_path))
    assert proc.returncode == 2 and "make bus-thresholds" in proc.stderr
