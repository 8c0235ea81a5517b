"""``reproduce`` (`make reproduce`): every study, their training runs planned first and trained
together, each study's results the bytes it writes alone; and the planning it rests on
(``repro.studies.kit.sweep.planning``)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from repro.cli import main
from repro.core.config import for_scale
from repro.reproduce import STUDIES, TIMING
from repro.runs.run_folder import CHECKPOINT
from repro.studies.kit.options import Workers
from repro.studies.kit.sweep import Planned, map_tasks, planning, run_sweep, run_sweeps
from repro.studies.transfer.study import TransferConfig, make_jobs


def _jobs():
    return [job for _, job in make_jobs(for_scale(TransferConfig, "smoke"), "smoke", 0)]


def test_a_plan_records_the_runs_to_train_and_trains_none(tmp_path):
    jobs = _jobs()
    with planning(finish=True) as plan, pytest.raises(Planned):
        run_sweep(jobs, tmp_path)
    assert plan.runs == [(job, tmp_path) for job in jobs]
    assert list(tmp_path.iterdir()) == []  # no run folder made


def test_a_plan_that_may_not_finish_stops_at_every_sweep_and_task_map(tmp_path):
    """Planned only, a command does no work at all: a sweep with nothing to train stops it too,
    and so does a map of tasks (the work of a study that trains its runs later)."""
    with planning(finish=False) as plan, pytest.raises(Planned):
        run_sweep([], tmp_path)
    with planning(finish=False), pytest.raises(Planned):
        map_tasks(print, [("never",)])
    assert plan.runs == []
    with planning(finish=True):  # may finish: a sweep with nothing to train returns
        assert run_sweep([], tmp_path) == []


def _csvs(folder: Path) -> dict[str, bytes]:
    """The result CSVs in ``folder`` by name, with their bytes (the timing record left out)."""
    return {p.name: p.read_bytes() for p in sorted(folder.glob("*.csv")) if p.name != TIMING}


@pytest.mark.slow
def test_two_sweeps_train_in_one_pool_on_dask_as_on_joblib(tmp_path):
    """The runs of two sweeps (two roots) in one pool, on a Dask cluster and on joblib's workers:
    the same checkpoints, each in its own sweep's folder."""
    distributed = pytest.importorskip("dask.distributed")
    first, second = _jobs()[:2]

    def sweeps(root: Path) -> list:
        return [([first], root / "a"), ([second], root / "b")]

    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  protocol="tcp://", host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        dask = Workers(scheduler=cluster.scheduler_address)
        on_dask = run_sweeps(sweeps(tmp_path / "dask"), dask)
    on_joblib = run_sweeps(sweeps(tmp_path / "joblib"), Workers(n_jobs=2))
    assert [[f.relative_to(tmp_path / "dask") for f in s] for s in on_dask] == [
        [Path("a", first.name)], [Path("b", second.name)]]
    for dask_runs, joblib_runs in zip(on_dask, on_joblib):
        for a, b in zip(dask_runs, joblib_runs):
            assert (a / CHECKPOINT).read_bytes() == (b / CHECKPOINT).read_bytes()


def _folders(root: Path) -> list[str]:
    return ["--results-dir", str(root / "res"), "--figures-dir", str(root / "fig"),
            "--runs-dir", str(root / "runs")]


@pytest.mark.slow
def test_reproduce_trains_the_studies_runs_in_one_pool_and_writes_what_each_writes_alone(
        tmp_path, capsys):
    """Three studies that share runs and hold several sweeps: every run trains in the first
    round's pool, once; each study then writes the bytes it writes when run alone; and the
    same command again trains nothing and changes no result."""
    studies = ["transfer", "transfer-order", "transfer-dt"]
    together = tmp_path / "together"
    assert main(["reproduce", "--scale", "smoke", "--studies", *studies,
                 *_folders(together)]) == 0
    timing = pd.read_csv(together / "res" / TIMING)
    assert list(timing.step) == ["training", *studies, "claims"]
    runs = [p for p in (together / "runs").rglob("progress.csv")]
    assert timing.runs.iloc[0] == len(runs) > 15  # transfer's 15 and the others' own
    alone = tmp_path / "alone"
    for name in studies:
        assert main([*STUDIES[name], "--scale", "smoke", *_folders(alone)]) == 0
    written = _csvs(together / "res")
    assert written == _csvs(alone / "res") and len(written) == 7
    capsys.readouterr()
    assert main(["reproduce", "--scale", "smoke", "--studies", *studies,
                 *_folders(together)]) == 0
    assert "training" not in set(pd.read_csv(together / "res" / TIMING).step)
    assert _csvs(together / "res") == written


def test_an_unknown_study_is_one_line_and_nothing_written(tmp_path, capsys):
    assert main(["reproduce", "--scale", "smoke", "--studies", "transfer", "nope",
                 *_folders(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--studies: must be names from race, " in err
    assert not (tmp_path / "res").exists() and not (tmp_path / "runs").exists()
