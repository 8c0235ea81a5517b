"""bench-wildfire: both engines under both policies, counted consistently; bad sizes refused."""

from __future__ import annotations

import numpy as np
import pytest

from repro.core.rollout import DecisionBatch
from repro.experiments.bench_wildfire import (BenchWildfireConfig, MLPPolicy, ScriptedPolicy,
                                              measure)


def test_measure_reports_both_engines_and_policies():
    frame = measure(BenchWildfireConfig(fast_episodes=30, reference_episodes=2), seed=4)
    assert sorted(zip(frame.engine, frame.policy)) == [
        ("fast", "mlp-32x2-tanh"), ("fast", "scripted"),
        ("reference", "mlp-32x2-tanh"), ("reference", "scripted")]
    assert (frame.decisions > frame.episodes).all()
    np.testing.assert_allclose(frame.decisions_per_second * frame.seconds, frame.decisions)
    np.testing.assert_allclose(frame.episodes_per_cpu_second * frame.cpu_seconds, frame.episodes)
    ref = frame[frame.engine == "reference"]
    np.testing.assert_allclose(ref.speedup_vs_reference, 1.0)


def test_policies_give_valid_actions_depending_on_the_rows():
    rng = np.random.default_rng(0)
    m = 400
    batch = DecisionBatch(obs=rng.normal(size=(m, 28)), episode=rng.integers(0, 5, m),
                          agent=rng.integers(0, 3, m), index=rng.integers(0, 1000, m))
    for policy in (MLPPolicy(28, 6, 32, seed=1), ScriptedPolicy(5, 3, 6, rng)):
        a = policy(batch)
        assert a.shape == (m,) and a.min() >= 0 and a.max() <= 5
        assert len(np.unique(a)) == 6  # every action occurs: the policies are stochastic
    scripted = ScriptedPolicy(5, 3, 6, np.random.default_rng(2))
    np.testing.assert_array_equal(scripted(batch), scripted(batch))  # a lookup, no state


@pytest.mark.parametrize("args, param", [
    (("--fast-episodes", "0"), "--fast-episodes"),
    (("--reference-episodes", "-1"), "--reference-episodes"),
])
def test_bad_sizes_are_one_line_exit_2_and_write_nothing(cli, tmp_path, args, param):
    res = tmp_path / "results"
    out = cli("bench-wildfire", "--scale", "smoke", "--results-dir", str(res), *args)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and param in lines[0], out.stderr
    assert not res.exists()
