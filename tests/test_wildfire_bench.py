"""bench-wildfire: both engines under both policies, counted consistently; bad sizes refused."""

from __future__ import annotations

import numpy as np
import pytest

from repro.experiments.bench_wildfire import WildfireBenchConfig, measure


def test_measure_reports_both_engines_and_policies():
    cfg = WildfireBenchConfig(fast_episodes=20, fast_repeats=2, reference_episodes=2)
    frame = measure(cfg, seed=4)
    assert sorted(zip(frame.engine, frame.policy)) == [
        ("fast", "mlp-32x32-tanh"), ("fast", "random"),
        ("reference", "mlp-32x32-tanh"), ("reference", "random")]
    assert frame.episodes.tolist() == [40, 40, 2, 2]
    assert (frame.decisions > frame.episodes).all()
    np.testing.assert_allclose(frame.decisions_per_second * frame.wall_seconds, frame.decisions)
    np.testing.assert_allclose(frame.episodes_per_cpu_second * frame.cpu_seconds, frame.episodes)
    np.testing.assert_allclose(frame.engine_decisions_per_cpu_second
                               * (frame.cpu_seconds - frame.policy_cpu_seconds), frame.decisions)
    ref = frame[frame.engine == "reference"]
    np.testing.assert_allclose(ref.speedup_vs_reference, 1.0)


@pytest.mark.parametrize("args, param", [
    (("--fast-episodes", "0"), "--fast-episodes"),
    (("--fast-repeats", "0"), "--fast-repeats"),
    (("--reference-episodes", "-1"), "--reference-episodes"),
])
def test_bad_sizes_are_one_line_exit_2_and_write_nothing(cli, tmp_path, args, param):
    res = tmp_path / "results"
    out = cli("bench-wildfire", "--scale", "smoke", "--results-dir", str(res), *args)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and param in lines[0], out.stderr
    assert not res.exists()
