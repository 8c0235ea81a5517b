"""Beyond the paper (issue 20): the drivers of X1 (advantage estimators) and X3 (transfer against
dT), their shared runs with the paper's studies, and their checks. Their bad input is tested with
the other studies' (tests/test_wildfire_experiments.py)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from repro.claims import NOT_RUN, beyond, registry, render
from repro.cli import main
from repro.core.config import for_scale
from repro.envs.bus import BusConfig
from repro.studies.advantage.estimators import MgaeStudyConfig, estimator_jobs
from repro.studies.bus import sweeps as bus_sweeps
from repro.studies.transfer import study as transfer
from repro.studies.transfer.dt_grid import TransferDtConfig
from tests.conftest import write_result_csv


def _main(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as exit_:  # argparse's errors
        return int(exit_.code)


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    """The transfer study, then X3 and X1 on the same run folders, at smoke scale."""
    tmp = tmp_path_factory.mktemp("beyond")
    common = ["--scale", "smoke", "--n-jobs", "1", "--runs-dir", str(tmp / "runs"),
              "--results-dir", str(tmp / "res"), "--figures-dir", str(tmp / "fig")]
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("REPRO_QUIET", "1")
        assert _main(["fig-transfer", *common]) == 0
        trained = set((tmp / "runs" / "transfer" / "smoke").iterdir())
        assert _main(["beyond-transfer-dt", *common]) == 0
        assert _main(["beyond-mgae", "--seeds", "1", *common]) == 0
    return tmp, trained


def test_the_m_gae_runs_are_the_studies_own():
    """X1's M-GAE jobs are the bus lambda sweep's lambda = 2 jobs and the transfer study's ED
    jobs, the same objects; the others differ from them in the estimator alone."""
    cfg = MgaeStudyConfig()
    for scale in ("smoke", "paper"):
        sweep = cfg.bus(scale)
        lam2 = [j for j in bus_sweeps.jobs(sweep, "lambda", 0, BusConfig())
                if j.train.lam == 2.0 and j.train.batch_episodes == sweep.lambda_batch]
        ed = [j for label, j in transfer.make_jobs(for_scale(transfer.TransferConfig, scale),
                                                   scale, 0) if label == "ED"]
        for base in (lam2, ed):
            jobs = estimator_jobs(cfg, base)
            assert [j for e, j in jobs if e == "m-gae"] == base
            for e, job in jobs:
                twin = next(b for b in base if b.train.seed == job.train.seed)
                assert dataclasses.replace(job.train, advantage="m-gae") == twin.train
                assert job.train.advantage == e and job.env_config == twin.env_config
    assert cfg.bus("paper").seeds == cfg.wildfire("paper").seeds == 5
    assert cfg.wildfire("paper").epochs == 300
    # lambda = 1 (wildfire): duration-gae is M-GAE, so it has no run of its own there
    assert {e for e, _ in estimator_jobs(cfg, ed)} == {"m-gae", "decision-gae"}


def test_the_dt_grid_contains_the_transfer_study():
    """X3's grid: 13 dT from 0.01 to 10 s, the transfer study's five among them as the very same
    jobs, listed first (their test sampling streams are their places in the list)."""
    for scale in ("smoke", "paper"):
        study = TransferDtConfig().study(scale)
        grid = transfer.make_jobs(study, scale, 0)
        paper = [(label, job) for label, job in transfer.make_jobs(
            for_scale(transfer.TransferConfig, scale), scale, 0) if "T_health" not in label]
        assert grid[:len(paper)] == paper
        dts = sorted({job.env_config.dt for _, job in grid if job.env_config.dt})
        assert len(dts) == 13 and np.allclose(dts, 10.0 ** np.arange(-2, 1.01, 0.25))
        assert all(job.env_config.t_health == 3.0 for _, job in grid)
    assert TransferDtConfig().study("paper").seeds == 5


def test_x3_trains_only_new_dt_and_repeats_the_study_rows(smoke):
    tmp, trained = smoke
    runs = tmp / "runs" / "transfer" / "smoke"
    assert trained < set(runs.iterdir())
    study, grid = (pd.read_csv(tmp / "res" / f"{n}.csv") for n in ("transfer", "transfer_dt_grid"))
    shared = study.merge(grid, on="run", suffixes=("", "_grid"))
    assert len(shared) == 6 and (shared.adr_ed == shared.adr_ed_grid).all()
    summary = pd.read_csv(tmp / "res" / "transfer_dt_grid_summary.csv")
    assert summary.dt.iloc[0] == 0 and summary.dt.is_monotonic_increasing and len(summary) == 14
    ours = summary.merge(pd.read_csv(tmp / "res" / "transfer_summary.csv"), on="simulator")
    assert len(ours) == 6 and (ours.ci_low_x == ours.ci_low_y).all()
    assert (tmp / "fig" / "transfer_dt_grid.png").exists()


def test_x1_outputs(smoke):
    tmp, _ = smoke
    runs = pd.read_csv(tmp / "res" / "beyond_mgae.csv")
    assert list(runs.groupby("env").estimator.unique().map(list)) == [
        ["m-gae", "decision-gae", "duration-gae"], ["m-gae", "decision-gae"]]
    # the wildfire's M-GAE policy is the transfer study's ED policy, tested with its streams
    ed = pd.read_csv(tmp / "res" / "transfer.csv").query("simulator == 'ED'").adr_ed
    assert runs.query("env == 'wildfire' and estimator == 'm-gae'").score.tolist() == ed.tolist()
    summary = pd.read_csv(tmp / "res" / "beyond_mgae_summary.csv")
    assert {"mean", "sem", "iqm", "ci_low", "ci_high", "mgae_ci"} <= set(summary.columns)
    assert (tmp / "fig" / "beyond_mgae.pdf").exists()
    assert beyond.check_x1(tmp / "res").verdict in ("PARTIAL", "FAIL")  # one run: no PASS


def test_beyond_claims_are_not_yet_run_without_results(tmp_path):
    ids = [c.id for c in registry() if c.id.startswith("X")]
    assert ids == ["X1", "X2", "X3", "X4", "X5", "X6"]
    for claim in registry():
        if claim.id in ids:
            v = claim.evaluate(tmp_path)
            assert v.verdict == NOT_RUN and "missing" in v.detail, v
    text = render(tmp_path)
    head, section = text.split("## Beyond the paper")
    assert "X1" not in head.split("## Details")[0] and "**6 questions: 6 not yet run**" in section
    assert head.splitlines()[2].startswith("**11 claims:")


def _grid(means: dict[float, float], half: float = 0.01, n: int = 5) -> pd.DataFrame:
    return pd.DataFrame([dict(simulator=f"dt{dt}", dt=dt, n_policies=n, mean=m, ci_low=m - half,
                              ci_high=m + half) for dt, m in means.items()])


def _races(rates: dict[float, float]) -> pd.DataFrame:
    return pd.DataFrame([dict(policy=p, n_agents=n, dt=dt, p_race_episode=min(1.0, 5 * r),
                              races_per_decision=r if n == 3 else 0.0)
                         for p in ("nearest", "random") for n in (2, 3)
                         for dt, r in rates.items()])


def test_x3_check(tmp_path, stored_intervals):
    """Holds up to the largest dT overlapping ED, breaks from the smallest below it; the verdict
    asks whether races (X2, N = 3) begin there; without races.csv it is not yet answered."""
    dts = [0.01, 0.1, 1.0, 10.0]
    write_result_csv(_grid({0.0: 3.0, **dict(zip(dts, [3.0, 3.005, 2.5, 2.0]))}),
                     tmp_path / "transfer_dt_grid_summary.csv")
    v = beyond.check_x3(tmp_path)
    assert v.verdict == NOT_RUN and "races.csv missing" in v.detail
    assert v.ours == "holds up to 0.1 s, breaks from 1 s"
    write_result_csv(_races(dict(zip(dts, [0.0, 0.01, 0.2, 0.9]))), tmp_path / "races.csv")
    v = beyond.check_x3(tmp_path)
    assert v.verdict == "PASS" and "races begin at 1 s" in v.ours, v
    assert "Races at 1 s: nearest 0.200 per decision" in v.detail
    write_result_csv(_races(dict(zip(dts, [0.0, 0.0, 0.0, 0.2]))), tmp_path / "races.csv")
    assert beyond.check_x3(tmp_path).verdict == "FAIL"  # races begin a decade later


def test_x3_names_an_overlap_beyond_the_break(tmp_path, stored_intervals):
    """A CI that overlaps ED's again above the break does not move "holds up to" past it."""
    dts = [0.1, 1.0, 3.0, 10.0]
    write_result_csv(_grid({0.0: 3.0, **dict(zip(dts, [3.0, 3.0, 2.5, 3.0]))}),
                     tmp_path / "transfer_dt_grid_summary.csv")
    assert beyond.check_x3(tmp_path).ours == ("holds up to 1 s, breaks from 3 s (overlaps again "
                                              "at 10 s)")


def test_x1_check(tmp_path, stored_intervals):
    def summary(bus_alt: float, fire_alt: float, n: int = 5) -> pd.DataFrame:
        rows = [("bus", "m-gae", -100.0), ("bus", "decision-gae", bus_alt),
                ("bus", "duration-gae", bus_alt), ("wildfire", "m-gae", 3.0),
                ("wildfire", "decision-gae", fire_alt)]
        return pd.DataFrame([dict(env=e, estimator=x, lam=2.0 if e == "bus" else 1.0, n_runs=n,
                                  mean=m, sem=0.0, iqm=m, ci_low=m - 0.01, ci_high=m + 0.01)
                             for e, x, m in rows])

    for (bus_alt, fire_alt, n), verdict in [((-200.0, 2.0, 5), "PASS"), ((-200.0, 3.0, 5),
                                            "PARTIAL"), ((-100.0, 3.5, 5), "FAIL"),
                                           ((-200.0, 2.0, 1), "PARTIAL")]:
        write_result_csv(summary(bus_alt, fire_alt, n), tmp_path / "beyond_mgae_summary.csv")
        v = beyond.check_x1(tmp_path)
        assert v.verdict == verdict, (bus_alt, fire_alt, n, v)
    assert "duration-gae is M-GAE exactly at lambda = 1" in v.detail


def test_bad_races_file_reads_incomplete(tmp_path):
    write_result_csv(_grid({0.0: 3.0, 1.0: 2.0}), tmp_path / "transfer_dt_grid_summary.csv")
    # a whole pair (CSV and sidecar) without the columns X3 reads
    write_result_csv(pd.DataFrame(dict(policy=["nearest"], dt=[1])), tmp_path / "races.csv")
    x3 = next(c for c in registry() if c.id == "X3")
    v = x3.evaluate(tmp_path)
    assert v.verdict == NOT_RUN and "incomplete" in v.detail
