"""Wildfire experiments: transfer sweep (C8, C9), behaviour frequencies (C6, C7), their checks."""

from __future__ import annotations

import dataclasses
import os
import signal
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from repro.claims import at_most_partial, wildfire as claims
from repro.envs.wildfire import QUIRKS, WildfireConfig, make_env
from repro.envs.wildfire.policies import (FLOWCHART_HOLD_ALONE, FLOWCHART_HOLD_SHARED,
                                          FLOWCHART_TARGET, FlowchartPolicy)
from repro.runs.run_folder import TIMING_COLUMNS
from repro.paper import TRANSFER_ADR
from repro.studies.kit.options import Workers
from repro.studies.kit.sweep import run_sweep
from repro.studies.transfer.study import TransferConfig, evaluate_policies, make_jobs
from repro.studies.wildfire.study import BehaviourConfig, behaviour_config, frequencies
from repro.studies.wildfire.study import evaluate
from tests.conftest import tree_snapshot, write_result_csv

pytestmark = pytest.mark.slow  # studies end to end, subprocesses: left out of make test-fast


def on_dask_of(cluster) -> Workers:
    """The workers of a test's Dask cluster."""
    return Workers(scheduler=cluster.scheduler_address)


def test_simulators_are_the_papers():
    sims = TransferConfig().simulators()
    assert list(sims) == list(TRANSFER_ADR)
    assert [s.dt for s in sims.values()] == [None, *(10.0 ** x for x in (-1, -0.5, 0, 0.5, 1)),
                                             1.0]
    assert [s.t_health for s in sims.values()] == [3.0] * 6 + [2.9999]
    assert len(QUIRKS) == 6
    assert all(getattr(s, q) for s in sims.values() for q in QUIRKS)
    corrected = TransferConfig(corrected=True)
    corrected_sims = [*corrected.simulators().values(), corrected.test_simulator()]
    assert not any(getattr(s, q) for s in corrected_sims for q in QUIRKS)
    # the same-instant order is not a quirk: the corrected semantics keep the released one
    assert all(s.same_instant_order == "released" for s in [*sims.values(), *corrected_sims])
    assert corrected.test_simulator().dt is None and corrected.test_simulator().t_health == 3.0


def test_frequencies_recover_the_flowchart_probabilities():
    """The C6 classification applied to the flowchart's own decisions gives back the flowchart's
    probabilities (within 4 binomial standard errors of each conditional count)."""
    cfg = WildfireConfig()
    rollout = evaluate(make_env(cfg), FlowchartPolicy(np.random.default_rng(3)), 150, 11)
    f = frequencies(rollout, cfg)
    target = np.asarray(FLOWCHART_TARGET) / np.sum(FLOWCHART_TARGET)
    expected = [("hold_alone", FLOWCHART_HOLD_ALONE, "n_alone"),
                ("hold_shared", FLOWCHART_HOLD_SHARED, "n_shared"),
                *((f"fly_rank_{k + 1}", target[k], "n_fly") for k in range(5))]
    for key, p, n in expected:
        assert f[n] > 200, key
        assert abs(f[key] - p) < 4 * np.sqrt(p * (1 - p) / f[n]), (key, f[key], p)
    # flying to the 3rd closest fire or closer stays in the cluster of the closest fire (clusters
    # are 1 m apart, fires 0.02 m), so the closest-cluster share is at least ranks 1-3's
    assert f["closest_cluster"] >= f["fly_rank_1"] + f["fly_rank_2"] + f["fly_rank_3"] - 0.02


try:
    from distributed.diagnostics.plugin import WorkerPlugin
except ImportError:  # the Dask tests skip themselves
    WorkerPlugin = object


def _jobs(labels):
    cfg = TransferConfig(seeds=1, epochs=2, batch_episodes=4, test_episodes=10)
    return cfg, [(lab, job) for lab, job in make_jobs(cfg, "smoke", 0) if lab in labels]


def test_sweep_on_a_local_dask_cluster_matches_joblib_and_skips_finished_runs(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    cfg, labelled = _jobs(("ED", "FS-10"))
    jobs = [job for _, job in labelled]
    # in-process workers (fast to start), but a real TCP scheduler on loopback
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  protocol="tcp://", host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        on_dask = run_sweep(jobs, tmp_path / "dask", on_dask_of(cluster))
        before = tree_snapshot(tmp_path / "dask")
        run_sweep(jobs, tmp_path / "dask", on_dask_of(cluster))
        assert tree_snapshot(tmp_path / "dask") == before  # finished runs are skipped
        tested_on_dask = evaluate_policies(cfg, labelled, on_dask, 0, on_dask_of(cluster))
    on_joblib = run_sweep(jobs, tmp_path / "joblib", Workers(n_jobs=1))
    a, b, c = (evaluate_policies(cfg, labelled, f, 0, Workers(n_jobs=n)).drop(columns="run")
               for f, n in ((on_dask, 1), (on_joblib, 1), (on_joblib, 2)))
    pd.testing.assert_frame_equal(a, b)
    pd.testing.assert_frame_equal(a, c)  # tested on two worker processes
    pd.testing.assert_frame_equal(a, tested_on_dask.drop(columns="run"))
    assert list(a.simulator) == ["ED", "FS-10"] and (a.epochs == 2).all()


class WorkOnItsOwnDisk(WorkerPlugin):
    """A Dask worker plugin: the worker's working folder is one the client never sees, so a
    relative --runs-dir names different folders on the two sides, as on machines without a shared
    disk."""

    def __init__(self, folder: str):
        self.folder = folder

    def setup(self, worker):
        import os

        os.makedirs(self.folder, exist_ok=True)
        os.chdir(self.folder)


def test_a_dask_sweep_needs_no_shared_disk(tmp_path, monkeypatch):
    """Worker processes whose disk differs from the client's: the run folders, interrupted or
    new, end up on the client's disk, as a joblib sweep writes them."""
    distributed = pytest.importorskip("dask.distributed")
    _, labelled = _jobs(("ED", "FS-1"))
    jobs = [job for _, job in labelled]
    monkeypatch.chdir(tmp_path)
    run_sweep(jobs, Path("joblib"), Workers(n_jobs=1))
    begun = dataclasses.replace(jobs[0], train=dataclasses.replace(jobs[0].train, epochs=1))
    run_sweep([begun], Path("dask"), Workers(n_jobs=1))  # one run begun on the client's disk...
    progress = Path("dask") / begun.name / "progress.csv"
    progress.write_text(progress.read_text() + "1,torn")  # ...and stopped in a write
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  protocol="tcp://", host="127.0.0.1",
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        client.register_plugin(WorkOnItsOwnDisk(str(tmp_path / "worker-disk")))
        with distributed.get_task_stream(client) as tasks:
            run_sweep(jobs, Path("dask"), on_dask_of(cluster))
    # one task per epoch, so a worker that dies loses at most the epoch in progress: the begun
    # run's second epoch, the other run's two
    assert sum("run_shipped_job" in t["key"] for t in tasks.data) == 3
    assert not (tmp_path / "worker-disk" / "dask").exists()
    for job in jobs:
        for name in ("config.json", "checkpoint.pt"):
            assert ((Path("dask") / job.name / name).read_bytes()
                    == (Path("joblib") / job.name / name).read_bytes()), (job.name, name)
        a, b = (pd.read_csv(Path(root) / job.name / "progress.csv").drop(columns=TIMING_COLUMNS)
                for root in ("dask", "joblib"))
        pd.testing.assert_frame_equal(a, b)


def _cluster(distributed):
    """A Dask cluster of one in-process worker behind a real TCP scheduler on loopback."""
    return distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                    protocol="tcp://", host="127.0.0.1", dashboard_address=None)


def test_a_dask_sweep_whose_scheduler_goes_away_stops_in_one_line_and_resumes(tmp_path,
                                                                            monkeypatch, capsys):
    """The cluster closes once the first epoch of two is in its run folder: one line naming
    --scheduler, exit 2, within seconds; the same command on another cluster resumes from the
    run folder and trains only the epoch left."""
    from repro.studies.kit import sweep
    from repro.runs.run_folder import epochs_done

    distributed = pytest.importorskip("dask.distributed")
    monkeypatch.setenv("REPRO_QUIET", "1")
    runs = tmp_path / "runs"
    argv = ["fig-transfer", "--scale", "smoke", "--simulator", "ED", "--test-episodes", "5",
            "--runs-dir", str(runs), "--results-dir", str(tmp_path / "res"),
            "--figures-dir", str(tmp_path / "fig")]
    cluster = _cluster(distributed)
    finished = sweep.is_finished

    def then_close(folder, epochs):  # asked by the client once it has written an epoch
        if epochs_done(folder) >= 1:
            cluster.close()
        return finished(folder, epochs)

    monkeypatch.setattr(sweep, "is_finished", then_close)
    try:
        t0 = time.perf_counter()
        assert _main([*argv, "--scheduler", cluster.scheduler_address]) == 2
        assert time.perf_counter() - t0 < 60
    finally:
        cluster.close()
    monkeypatch.undo()
    monkeypatch.setenv("REPRO_QUIET", "1")
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--scheduler: must be a Dask cluster that answers" in err, err
    assert "lost the scheduler" in err and "running the same command again resumes" in err
    folder = runs / "transfer" / "smoke" / "ed-th3-seed0"
    assert epochs_done(folder) == 1 and not (tmp_path / "res").exists()
    with _cluster(distributed) as again, distributed.Client(again) as client, \
            distributed.get_task_stream(client) as tasks:
        assert _main([*argv, "--scheduler", again.scheduler_address]) == 0
    assert sum("run_shipped_job" in t["key"] for t in tasks.data) == 1  # the second epoch
    assert epochs_done(folder) == 2


def test_a_dask_sweep_whose_workers_go_away_stops_after_the_silence(tmp_path, monkeypatch):
    """The scheduler stays but its only worker leaves once the first epoch is in its folder: no
    epoch finishes any more, and the sweep stops (UsageError naming --scheduler) once
    CLUSTER_SILENCE has passed, here 3 s, instead of waiting for ever."""
    from repro.core.errors import UsageError
    from repro.studies.kit import sweep
    from repro.runs.run_folder import epochs_done

    distributed = pytest.importorskip("dask.distributed")
    monkeypatch.setattr(sweep, "CLUSTER_SILENCE", 3.0)
    _, labelled = _jobs(("ED",))
    jobs = [dataclasses.replace(job, train=dataclasses.replace(job.train, epochs=3))
            for _, job in labelled]
    with _cluster(distributed) as cluster:
        finished = sweep.is_finished

        def then_leave(folder, epochs):  # asked by the client once it has written an epoch
            if epochs_done(folder) >= 1 and cluster.scheduler.workers:
                cluster.scale(0)
                deadline = time.monotonic() + 20
                while cluster.scheduler.workers and time.monotonic() < deadline:
                    time.sleep(0.05)
                assert not cluster.scheduler.workers
            return finished(folder, epochs)

        monkeypatch.setattr(sweep, "is_finished", then_leave)
        t0 = time.perf_counter()
        with pytest.raises(UsageError, match="--scheduler") as caught:
            run_sweep(jobs, tmp_path / "runs", on_dask_of(cluster))
        assert 3 <= time.perf_counter() - t0 < 60
    assert "no task finished within 3 s" in str(caught.value)
    assert epochs_done(tmp_path / "runs" / jobs[0].name) == 1


def _sleep_then(seconds: float, value: int) -> int:
    time.sleep(seconds)
    return value


def test_map_tasks_on_dask_keeps_the_order_and_stops_when_the_workers_go_away(monkeypatch):
    """Evaluation tasks on Dask come back in the tasks' order; when the only worker leaves with
    tasks pending, the call stops (UsageError naming --scheduler) once CLUSTER_SILENCE has
    passed, here 3 s: it waited in client.gather for ever."""
    from repro.core.errors import UsageError
    from repro.studies.kit import sweep

    distributed = pytest.importorskip("dask.distributed")
    with _cluster(distributed) as cluster:
        tasks = [(0.3 - 0.1 * i, i) for i in range(3)]  # the last submitted finishes first
        assert sweep.map_tasks(_sleep_then, tasks, on_dask_of(cluster)) == [0, 1, 2]
        monkeypatch.setattr(sweep, "CLUSTER_SILENCE", 3.0)
        cluster.scale(0)
        deadline = time.monotonic() + 20
        while cluster.scheduler.workers and time.monotonic() < deadline:
            time.sleep(0.05)
        t0 = time.perf_counter()
        with pytest.raises(UsageError, match="--scheduler") as caught:
            sweep.map_tasks(_sleep_then, tasks, on_dask_of(cluster))
        assert 3 <= time.perf_counter() - t0 < 60
    assert "no task finished within 3 s" in str(caught.value)


def _die(signum: int) -> int:
    """A task whose worker process dies of the signal ``signum`` (SIGKILL: as one the system kills
    for want of memory; SIGSEGV: as compiled code that crashes)."""
    os.kill(os.getpid(), signum)
    time.sleep(60)  # the signal arrives meanwhile
    return signum


def test_a_worker_that_dies_is_one_line_on_joblib_and_on_dask(monkeypatch, capsys, tmp_path):
    """joblib's TerminatedWorkerError and Dask's KilledWorker become WorkerDied, which the command
    line prints as one line (exit 1)."""
    from repro.core.errors import WorkerDied
    from repro.studies.kit import sweep
    from repro.studies.races import race

    with pytest.raises(WorkerDied, match="joblib: SIGKILL: most often the system out of memory "
                       r"\(fewer --n-jobs") as caught:
        sweep.map_tasks(_die, [(signal.SIGKILL,), (signal.SIGKILL,)], Workers(n_jobs=2))
    assert "\n" not in str(caught.value) and "runs these tasks again" in str(caught.value)
    with pytest.raises(WorkerDied, match="joblib: SIGSEGV: a crash in compiled code") as crashed:
        sweep.map_tasks(_die, [(signal.SIGSEGV,), (signal.SIGSEGV,)], Workers(n_jobs=2))
    assert "out of memory" not in str(crashed.value) and "\n" not in str(crashed.value)
    distributed = pytest.importorskip("dask.distributed")
    import dask

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                     protocol="tcp://", host="127.0.0.1",
                                     dashboard_address=None) as cluster:
        with pytest.raises(WorkerDied, match="Dask: every worker that ran one task died") as caught:
            sweep.map_tasks(_die, [(signal.SIGKILL,)], on_dask_of(cluster))
    assert "\n" not in str(caught.value)

    def dies(*args, **kwargs):
        raise caught.value

    monkeypatch.setattr(race, "run_study", dies)
    monkeypatch.setenv("REPRO_QUIET", "1")
    capsys.readouterr()
    assert _main(["race", "--scale", "smoke", "--results-dir", str(tmp_path / "r"),
                  "--no-figure"]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "a worker process died" in lines[0]


def _main(argv: list[str]) -> int:
    from repro.cli import main

    try:
        return main(argv)
    except SystemExit as exit_:  # argparse's errors
        return int(exit_.code)


def test_fig_transfer_cli_smoke(tmp_path, monkeypatch):
    """The whole command in process (n_jobs=1 runs the sweep sequentially here); a second run
    skips the finished training runs and rewrites byte-identical CSVs."""
    monkeypatch.setenv("REPRO_QUIET", "1")
    outs = []
    for i in range(2):
        assert _main(["fig-transfer", "--scale", "smoke", "--test-episodes", "5", "--n-jobs", "1",
                      "--runs-dir", str(tmp_path / "runs"),
                      "--results-dir", str(tmp_path / f"r{i}"),
                      "--figures-dir", str(tmp_path / "fig")]) == 0
        outs.append([(tmp_path / f"r{i}" / n).read_bytes()
                     for n in ("transfer.csv", "transfer_summary.csv")])
    assert outs[0] == outs[1]
    summary = pd.read_csv(tmp_path / "r0" / "transfer_summary.csv")
    assert list(summary.simulator) == list(TRANSFER_ADR) and (summary.n_policies == 1).all()
    assert all((tmp_path / "fig" / f"transfer.{ext}").exists() for ext in ("png", "pdf"))
    # a subset of the simulators, here the T_health variant without its FS-1: the figure is drawn,
    # and the policy scores as in the whole study (its test stream is its run's, not its place's)
    variant = "FS-1 (T_health=2.9999)"
    assert _main(["fig-transfer", "--scale", "smoke", "--test-episodes", "5", "--n-jobs", "1",
                  "--simulator", variant, "--runs-dir", str(tmp_path / "runs"),
                  "--results-dir", str(tmp_path / "subset"),
                  "--figures-dir", str(tmp_path / "subset_fig")]) == 0
    whole, subset = (pd.read_csv(tmp_path / d / "transfer.csv").drop(columns="wall_seconds",
                                                                       errors="ignore")
                     for d in ("r0", "subset"))
    assert len(subset) == 1 and subset.iloc[0].to_dict() == (
        whole[whole.simulator == variant].iloc[0].to_dict())
    assert (tmp_path / "subset_fig" / "transfer.png").exists()


STUDY_BAD_INPUT = [["--seeds", "0"], ["--n-jobs", "0"], ["--scale", "huge"], ["--seed", "-1"],
                   ["--scheduler", "notanaddress", "--scale", "smoke"]]
"""Bad options of every training study (the beyond-the-paper ones have only these)."""


@pytest.mark.parametrize("command, argv", [
    *((c, a) for c in ("fig-transfer", "wildfire-behaviour")
      for a in [*STUDY_BAD_INPUT, ["--test-episodes", "0"], ["--epochs", "0"]]),
    *((c, a) for c in ("beyond-mgae", "beyond-transfer-dt") for a in STUDY_BAD_INPUT)])
def test_bad_input_writes_nothing(tmp_path, monkeypatch, capsys, command, argv):
    monkeypatch.chdir(tmp_path)
    assert _main([command, *argv]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1, err
    assert list(tmp_path.iterdir()) == []


def test_sweep_refuses_finished_runs_made_with_other_settings(tmp_path, capsys):
    """A runs folder holding finished runs of other settings is an error (exit 2), not a cache:
    nothing is trained, evaluated or written."""
    runs, res = tmp_path / "runs", tmp_path / "res"
    argv = ["wildfire-behaviour", "--scale", "smoke", "--test-episodes", "5", "--n-jobs", "1",
            "--runs-dir", str(runs), "--results-dir", str(res)]
    assert _main(argv) == 0
    before = tree_snapshot(runs, res)
    capsys.readouterr()
    assert _main([*argv, "--max-decisions", "5"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--runs-dir" in err, err
    assert tree_snapshot(runs, res) == before


def test_max_decisions_0_lifts_the_decision_limit():
    import argparse

    from repro.studies.wildfire import behaviour as wildfire_behaviour

    parser = argparse.ArgumentParser()
    wildfire_behaviour.add_arguments(parser)

    def limit(*argv: str) -> int | None:
        return behaviour_config(BehaviourConfig, parser.parse_args(argv)).max_decisions

    assert limit("--scale", "paper") == 1000 and limit("--scale", "quick") == 1000
    assert limit("--scale", "paper", "--max-decisions", "0") is None
    assert limit("--scale", "quick", "--max-decisions", "7") == 7


def _summary(means: dict[str, float], half_width: float, n: int = 5) -> pd.DataFrame:
    return pd.DataFrame([dict(simulator=k, mean=m, sem=half_width / 2, ci_low=m - half_width,
                              ci_high=m + half_width, n_policies=n) for k, m in means.items()]
                        ).set_index("simulator")


def test_c8_c9_verdicts_follow_the_intervals():
    paper = {k: m for k, (m, _) in TRANSFER_ADR.items()}
    s = _summary(paper, 0.03)
    assert claims.c8_verdict(s)[0] == "PASS" and claims.c9_verdict(s)[0] == "PASS"
    flat = _summary({k: 2.7 for k in TRANSFER_ADR}, 0.03)
    assert claims.c8_verdict(flat)[0] == "PARTIAL"  # the small-dT part holds, degradation not
    assert claims.c9_verdict(flat)[0] == "FAIL"
    inverted = _summary({**paper, "ED": 1.0}, 0.03)
    assert claims.c8_verdict(inverted)[0] == "FAIL"
    better = _summary({**paper, "FS-0.1": 2.9}, 0.03)  # transfers better than ED: not "as well"
    assert claims.c8_verdict(better) == ("PARTIAL", "failed: FS-0.1 (CI above ED's)")
    one = _summary(paper, 0.0, n=1)
    assert at_most_partial("PASS", int(one.n_policies.min()))[0] == "PARTIAL"
    assert at_most_partial("PASS", 2) == ("PASS", "")


@pytest.mark.parametrize("learned, flowchart, verdict", [
    ([3.0, 3.1, 2.9], 2.1, "PASS"),       # about 30% worse
    ([3.0, 3.1, 2.9], 2.7, "PARTIAL"),    # worse for every policy, by about 10%
    ([3.0, 2.0, 2.9], 2.5, "FAIL"),       # better than one policy
    ([-2.0, -2.1, -1.9], -1.4, "FAIL"),   # the flowchart is better, yet the ratio reads 30% worse
])
def test_c7_verdict_follows_the_adr_ratio(tmp_path, learned, flowchart, verdict):
    learned = np.array(learned)
    write_result_csv(pd.DataFrame(dict(adr_learned=learned, adr_flowchart=flowchart,
                                       flowchart_worse=1.0 - flowchart / learned)),
                     tmp_path / "wildfire_behaviour.csv")
    assert claims.check_c7(tmp_path).verdict == verdict


def test_fs1_trained_with_t_health_2_9999_transfers_worse_than_with_3(tmp_path, monkeypatch):
    """C9 at a small budget (30 epochs x 60 episodes, 300 ED test episodes): the FS-1 policy trained
    with T_health = 2.9999 scores clearly below the one trained with 3.0. Measured while choosing
    this budget, ADR on ED (3.0 vs 2.9999): seed 0 1.93 vs 1.10, seed 1 1.66 vs 1.25, seed 2 1.87
    vs 1.09; the test-episode standard error is about 0.05, so the margin asserted is not luck.

    Quirk Q3 off (train and test): with the released semantics' unclamped health observation the
    margin reverses at this budget (seeds 0, 1, 2: 1.90 vs 2.07, 1.98 vs 2.00, 1.89 vs 2.16); with
    all released semantics but Q3, seed 0 gives 2.00 vs 1.03. Whether C9 holds with Q3 at the
    paper's budget is for the transfer study to tell."""
    no_q3 = {**dict.fromkeys(QUIRKS, True), "quirk_q3_unclamped_health": False}
    monkeypatch.setattr(TransferConfig, "quirks", lambda self: no_q3)
    cfg = TransferConfig(seeds=1, epochs=30, batch_episodes=60, test_episodes=300,
                         log10_dts=(0.0,))
    labelled = [(lab, job) for lab, job in make_jobs(cfg, "smoke", 0) if lab.startswith("FS-1")]
    folders = run_sweep([job for _, job in labelled], tmp_path, Workers(n_jobs=1))
    adr = evaluate_policies(cfg, labelled, folders, 0).set_index("simulator").adr_ed
    assert adr["FS-1 (T_health=2.9999)"] < adr["FS-1"] - 0.3, adr.to_dict()


def test_frequency_counts_of_separate_batches_add_up_to_the_whole(monkeypatch):
    """The behaviour driver counts batch by batch (to drop observations); that must give exactly
    the frequencies of the joined rollout."""
    from repro.studies.wildfire import study as wildfire_eval
    from repro.studies.wildfire.study import frequency_counts, shares

    monkeypatch.setattr(wildfire_eval, "BATCH_EPISODES", 20)
    cfg = WildfireConfig()
    counts = []
    whole = evaluate(make_env(cfg), FlowchartPolicy(np.random.default_rng(3)), 70, 11,
                     on_batch=lambda batch: counts.append(frequency_counts(batch, cfg)))
    assert len(counts) == 4
    total = {key: sum(c[key] for c in counts) for key in counts[0]}
    assert shares(total) == frequencies(whole, cfg)
    names = ["hold_shared", "hold_alone", *(f"fly_rank_{k}" for k in range(1, 6)),
             "closest_cluster"]
    assert list(shares(total)) == [*names, *(n + "_ex_stay" for n in names), "stay_flight",
                                   "n_shared", "n_alone", "n_fly", "n_shared_ex_stay",
                                   "n_alone_ex_stay", "n_fly_ex_stay", "n_decisions"]


def test_stay_flights_are_flights_to_the_fire_the_uav_is_at():
    """A stay flight (almost always) lasts one latency in ED; the frequencies without them count
    every other decision as before."""
    from repro.studies.wildfire.study import frequency_counts

    cfg = WildfireConfig()
    ro = make_env(cfg).rollout(FlowchartPolicy(np.random.default_rng(5)), 40, 2)
    c = frequency_counts(ro, cfg)
    # only the closest fire can be that close
    stay = (ro.actions == 0) & (ro.obs[:, 2] < cfg.at_fire_tol)
    assert c["stay_flight_events"] == stay.sum() > 0
    # a UAV cut off within at_fire_tol of a fire flies the rest of the way: at most 0.07 s
    assert np.all(ro.durations[stay] <= cfg.decision_latency + cfg.at_fire_tol / cfg.v_uav)
    assert np.median(ro.durations[stay]) < 2 * cfg.decision_latency
    assert c["n_fly"] - c["n_fly_ex_stay"] == c["stay_flight_events"]
    assert c["fly_rank_1_events"] - c["fly_rank_1_events_ex_stay"] == c["stay_flight_events"]
    assert c["hold_alone_events"] == c["hold_alone_events_ex_stay"]  # a hold is never a flight


@pytest.mark.parametrize("finished, stale", [("2026-11-22T10:00:00Z", True),
                                             ("2026-11-25T04:00:00Z", False)])
def test_a_result_of_the_earlier_semantics_reads_not_yet_run(tmp_path, finished, stale):
    """C7 on a result finished before the engines followed the released simulator: "not yet
    run", with the verdict it had; after: the verdict itself."""
    learned = np.array([3.0, 3.1, 2.9])
    write_result_csv(pd.DataFrame(dict(adr_learned=learned, adr_flowchart=2.1,
                                       flowchart_worse=1.0 - 2.1 / learned)),
                     tmp_path / "wildfire_behaviour.csv", finished_utc=finished)
    v = claims.on_current_semantics(claims.check_c7, claims.BEHAVIOUR)(tmp_path)
    assert v.verdict == ("not yet run" if stale else "PASS")
    assert ("it read PASS" in v.detail) == stale == v.outdated



def test_heuristics_play_the_transfer_studys_test_episodes(tmp_path):
    """wildfire-heuristics: every heuristic under both semantics, on the transfer study's test
    seed; nearest far above random; the same command writes the same bytes."""
    argv = ["wildfire-heuristics", "--scale", "smoke", "--results-dir", str(tmp_path)]
    assert _main(argv) == 0
    table = pd.read_csv(tmp_path / "wildfire_heuristics.csv")
    assert set(zip(table.semantics, table.policy)) == {
        (s, p) for s in ("released", "corrected") for p in ("random", "nearest", "flowchart")}
    adr = table.set_index(["semantics", "policy"]).adr
    assert adr["released", "nearest"] > adr["released", "random"] + 1.0
    before = (tmp_path / "wildfire_heuristics.csv").read_bytes()
    assert _main(argv) == 0 and (tmp_path / "wildfire_heuristics.csv").read_bytes() == before


def test_an_ablation_trains_only_the_simulators_asked_with_the_quirks_asked_off(tmp_path):
    """fig-transfer --no-quirk q3 --simulator ...: transfer_no_q3*, those simulators only, Q3 off
    in training and test; claim C9 reports it."""
    from repro.studies.transfer.study import TransferConfig

    argv = ["fig-transfer", "--scale", "smoke", "--no-quirk", "q3", "--simulator", "FS-1",
            "--simulator", "FS-1 (T_health=2.9999)", "--results-dir", str(tmp_path / "r"),
            "--figures-dir", str(tmp_path / "f"), "--runs-dir", str(tmp_path / "runs")]
    assert _main(argv) == 0
    summary = pd.read_csv(tmp_path / "r" / "transfer_no_q3_summary.csv")
    assert list(summary.simulator) == ["FS-1", "FS-1 (T_health=2.9999)"]
    cfg = TransferConfig(quirks_off=("q3",))
    assert not cfg.test_simulator().quirk_q3_unclamped_health
    assert cfg.test_simulator().quirk_q1_stale_attack
    assert "Released semantics with Q3 off (1 policies each)" in claims._ablation_lines(
        tmp_path / "r", "")
    for bad in (["--no-quirk", "q9"], ["--simulator", "FS-2"]):
        assert _main(["fig-transfer", "--scale", "smoke", *bad, "--results-dir",
                      str(tmp_path / "bad")]) == 2
    assert not (tmp_path / "bad").exists()


@pytest.mark.parametrize("cut, text", [
    ((0, 0), "No episode reached the decision limit (1000 decisions per UAV)"),
    ((30, 4), "cut 30 of 1,200 training episodes (2.5%) and 4 of 40 test episodes (10.0%)"),
])
def test_the_claims_say_how_many_episodes_the_decision_limit_cut(tmp_path, cut, text):
    table = pd.DataFrame(dict(epochs=[3, 3], batch_episodes=200, test_episodes=20,
                              max_decisions=1000, train_truncated=[cut[0], 0],
                              test_truncated=[0, cut[1]]))
    write_result_csv(table, tmp_path / "transfer.csv")
    assert text in claims._cut_line(tmp_path / "transfer.csv")
    write_result_csv(table.drop(columns=["train_truncated", "test_truncated"]),
                     tmp_path / "old.csv")
    assert claims._cut_line(tmp_path / "old.csv") == ""  # made before the columns existed


def test_a_policys_stream_is_keyed_by_its_run():
    """The same run gets the same stream under a root seed, whatever else a study tests; other
    runs, streams or seeds get others."""
    from repro.studies.kit.sweep import policy_stream

    state = policy_stream(0, 1, "fs1-th3-seed0").generate_state(4).tolist()
    assert state == policy_stream(0, 1, "fs1-th3-seed0").generate_state(4).tolist()
    others = [policy_stream(0, 1, "fs1-th3-seed1"), policy_stream(0, 2, "fs1-th3-seed0"),
              policy_stream(1, 1, "fs1-th3-seed0")]
    assert all(o.generate_state(4).tolist() != state for o in others)
