"""bench-wildfire: both engines under both policies, counted consistently; bad sizes refused."""

from __future__ import annotations

import numpy as np
import pytest

from repro.experiments.bench_wildfire import WildfireBenchConfig, measure


def test_measure_reports_both_engines_and_policies():
    cfg = WildfireBenchConfig(fast_episodes=20, reference_episodes=2, repeats=1)
    frame = measure(cfg, seed=4)
    assert sorted(zip(frame.engine, frame.policy)) == [
        ("fast", "mlp-32x32-tanh"), ("fast", "random"),
        ("reference", "mlp-32x32-tanh"), ("reference", "random")]
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
    assert three.episodes.tolist() == [60, 60, 6, 6] and (three.batches == 3).all()
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
