"""``python -m repro plot-runs``: training curves of run folders, grouped by setting, with
across-seed intervals; bad input is one line, exit 2, nothing written."""

from __future__ import annotations

import hashlib
import json
import shutil

import numpy as np
import pandas as pd
import pytest
import scipy.stats as sps

from repro.studies.training.plot_runs import curve, groups, read_runs
from tests.conftest import run_cli, tree_snapshot

pytestmark = pytest.mark.slow  # studies end to end, subprocesses: left out of make test-fast


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    """Two tiny wildfire runs (train --scale smoke), seeds 0 and 1."""
    root = tmp_path_factory.mktemp("runs")
    for seed in (0, 1):
        done = run_cli("train", "--env", "wildfire", "--scale", "smoke", "--seed", str(seed),
                       "--out", str(root / f"seed{seed}"))
        assert done.returncode == 0, done.stderr
    return root / "seed0", root / "seed1"


def test_plots_two_runs_as_one_setting_with_their_interval(two_runs, tmp_path):
    out = tmp_path / "curves.png"
    done = run_cli("plot-runs", *map(str, two_runs), "--out", str(out))
    assert done.returncode == 0, done.stderr
    assert out.stat().st_size > 10_000 and out.read_bytes()[:4] == b"\x89PNG"
    assert "(2 runs)" in done.stdout
    tables = [pd.read_csv(run / "progress.csv") for run in two_runs]
    values = np.stack([t["average_discounted_return"] for t in tables])
    c = curve(tables, "average_discounted_return")
    np.testing.assert_allclose(c["mean"], values.mean(axis=0))
    np.testing.assert_allclose(c["half"], values.std(axis=0, ddof=1) / np.sqrt(2)
                               * sps.t.ppf(0.975, 1))
    side = json.loads((tmp_path / "curves.provenance.json").read_text())
    assert side["figures"] == {"curves.png": hashlib.sha256(out.read_bytes()).hexdigest()}
    assert [s["csv"] for s in side["sources"]] == [str(run / "progress.csv") for run in two_runs]
    assert [s["csv_sha256"] for s in side["sources"]] == [
        hashlib.sha256((run / "progress.csv").read_bytes()).hexdigest() for run in two_runs]
    pdf = tmp_path / "curves.pdf"
    assert run_cli("plot-runs", str(two_runs[0]), "--out", str(pdf), "--metric",
                   "entropy").returncode == 0
    assert pdf.read_bytes()[:4] == b"%PDF"


def test_groups_by_setting_and_names_the_difference(two_runs, tmp_path):
    other = tmp_path / "lam2"
    shutil.copytree(two_runs[0], other)
    config = json.loads((other / "config.json").read_text())
    config["train"]["lam"] = 2.0
    (other / "config.json").write_text(json.dumps(config))
    labelled = groups(read_runs([str(two_runs[0]), str(other), str(two_runs[1])]))
    assert [(label, len(tables)) for label, tables in labelled] == [
        ("lam=1.0 (2 runs)", 2), ("lam=2.0 (1 run)", 1)]
    # the simulators, as the paper names them
    config["train"]["lam"], config["env"]["dt"] = 1.0, 1.0
    (other / "config.json").write_text(json.dumps(config))
    labelled = groups(read_runs([str(two_runs[0]), str(other)]))
    assert [label for label, _ in labelled] == ["ED (1 run)", "FS-1 (1 run)"]


@pytest.mark.parametrize("args, message", [
    (["{missing}"], "RUN_DIR: must be run folders"),
    (["{run}", "--out", "{tmp}/curves.svg"], "--out: must be a file name ending in .png or .pdf"),
    (["{run}", "--out", "{run}/progress.csv/curves.png"], "--out: must be a writable folder"),
    (["{run}", "--metric", "loss"], "--metric: must be one of"),
    (["{tmp}"], "RUN_DIR: must be run folders"),
])
def test_bad_input_is_one_line_exit_2_nothing_written(two_runs, tmp_path, args, message):
    args = [a.format(missing=tmp_path / "nothing", run=two_runs[0], tmp=tmp_path) for a in args]
    before = tree_snapshot(tmp_path, two_runs[0])
    done = run_cli("plot-runs", *args, cwd=tmp_path)  # the default --out: runs.png there
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and message in done.stderr, done.stderr
    assert tree_snapshot(tmp_path, two_runs[0]) == before
