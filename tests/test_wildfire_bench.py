"""bench-wildfire: both engines under both policies, counted consistently; bad sizes refused."""

from __future__ import annotations

import numpy as np
import pytest

from repro.envs.wildfire import WildfireConfig
from repro.learn.trained_policy import load_trained_run
from repro.studies.bench.wildfire import WildfireBenchConfig, measure

pytestmark = pytest.mark.slow  # studies end to end, subprocesses: left out of make test-fast

MLPS = ("authors-mlp-32-tanh", "suite-mlp-32x32-tanh")
"""The benchmarks' policies: each learner's fresh network."""


def test_measure_reports_both_engines_and_policies():
    cfg = WildfireBenchConfig(fast_episodes=20, reference_episodes=2, repeats=1)
    frame = measure(cfg, seed=4)
    assert sorted(zip(frame.engine, frame.policy)) == sorted(
        (engine, policy) for engine in ("fast", "fast-step-api", "reference")
        for policy in (*MLPS, "random"))
    for policy in (*MLPS, "random"):  # the rollouts' decisions, or a step more
        rollouts, steps = (frame[(frame.engine == engine) & (frame.policy == policy)].iloc[0]
                           for engine in ("fast", "fast-step-api"))
        assert rollouts.decisions <= steps.decisions < rollouts.decisions + 20 * 100
    assert (frame.decisions > frame.episodes).all()
    # one batch: the medians are the totals' rates
    np.testing.assert_allclose(frame.decisions_per_second * frame.wall_seconds, frame.decisions)
    np.testing.assert_allclose(frame.episodes_per_cpu_second * frame.cpu_seconds, frame.episodes)
    np.testing.assert_allclose(frame.engine_decisions_per_cpu_second
                               * (frame.cpu_seconds - frame.policy_cpu_seconds), frame.decisions)
    ref = frame[frame.engine == "reference"]
    np.testing.assert_allclose(ref.speedup_vs_reference, 1.0)


def test_repeats_run_more_batches_of_other_episodes():
    one = measure(WildfireBenchConfig(fast_episodes=20, reference_episodes=2, repeats=1), seed=4)
    three = measure(WildfireBenchConfig(fast_episodes=20, reference_episodes=2, repeats=3), seed=4)
    assert three.episodes.tolist() == [60, 60, 60, 6, 6, 6, 60, 60, 60]
    assert (three.batches == 3).all()
    assert (three.decisions != 3 * one.decisions).all()  # batches 2 and 3 draw other episodes
    assert np.isfinite(three.select_dtypes("number")).all().all()


@pytest.mark.parametrize("args, param", [
    (("--fast-episodes", "0"), "--fast-episodes"),
    (("--repeats", "0"), "--repeats"),
    (("--reference-episodes", "-1"), "--reference-episodes"),
])
def test_bad_sizes_are_one_line_exit_2_and_write_nothing(cli, tmp_path, args, param):
    res = tmp_path / "results"
    out = cli("bench-wildfire", "--scale", "smoke", "--results-dir", str(res), *args)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and param in lines[0], out.stderr
    assert not res.exists()


@pytest.fixture(scope="module")
def trained_run(tmp_path_factory):
    """A one-epoch wildfire run with a decision limit, and a bus run, as the train command makes
    them."""
    from repro.cli import main

    root = tmp_path_factory.mktemp("runs")
    assert main(["train", "--env", "wildfire", "--scale", "smoke", "--epochs", "1",
                 "--max-decisions", "4", "--out", str(root / "wildfire")]) == 0
    assert main(["train", "--env", "bus", "--scale", "smoke", "--epochs", "1",
                 "--out", str(root / "bus")]) == 0
    return root


def test_checkpoint_times_the_trained_policy_on_its_runs_environment(trained_run):
    cfg = WildfireBenchConfig(fast_episodes=20, reference_episodes=2, repeats=1)
    frame = measure(cfg, seed=4,
                    trained=load_trained_run(trained_run / "wildfire" / "checkpoint.pt",
                                             "wildfire"))
    assert sorted(zip(frame.engine, frame.policy)) == [
        ("fast", "checkpoint"), ("fast", "random"), ("fast-step-api", "checkpoint"),
        ("fast-step-api", "random"), ("reference", "checkpoint"), ("reference", "random")]
    # the run's limit of 4 decisions per UAV holds in every episode of both engines (the step
    # API runs more episodes)
    n_uavs = WildfireConfig().n_agents
    rollouts = frame[frame.engine != "fast-step-api"]
    assert (rollouts.decisions <= rollouts.episodes * n_uavs * 4).all()
    unlimited = measure(cfg, seed=4)
    assert (unlimited.decisions > unlimited.episodes * n_uavs * 4).all()


@pytest.mark.parametrize("which", ["bus", "missing", "not-a-checkpoint"])
def test_checkpoint_of_another_env_or_none_is_refused(cli, tmp_path, trained_run, which):
    path = {"bus": trained_run / "bus" / "checkpoint.pt", "missing": tmp_path / "none.pt",
            "not-a-checkpoint": trained_run / "wildfire" / "progress.csv"}[which]
    res = tmp_path / "results"
    out = cli("bench-wildfire", "--scale", "smoke", "--results-dir", str(res),
              "--checkpoint", str(path))
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "--checkpoint" in lines[0], out.stderr
    assert not res.exists()


def test_checkpoint_benchmark_writes_its_own_csv(cli, tmp_path, trained_run):
    res = tmp_path / "results"
    out = cli("bench-wildfire", "--scale", "smoke", "--results-dir", str(res),
              "--checkpoint", str(trained_run / "wildfire" / "checkpoint.pt"))
    assert out.returncode == 0, out.stderr
    assert sorted(p.name for p in res.iterdir()) == ["bench_wildfire_checkpoint.csv",
                                                     "bench_wildfire_checkpoint.provenance.json"]
