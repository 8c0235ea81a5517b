"""bench-bus at smoke scale: one row per engine and policy, rates consistent with the times."""

from __future__ import annotations

import numpy as np
import pandas as pd

from repro.cli import main

MLPS = ("authors-mlp-32-tanh", "suite-mlp-32x32-tanh")
"""The benchmarks' policies: each learner's fresh network."""


def test_bench_bus_smoke(tmp_path):
    assert main(["bench-bus", "--scale", "smoke", "--results-dir", str(tmp_path)]) == 0
    df = pd.read_csv(tmp_path / "bench_bus.csv")
    assert sorted(zip(df.engine, df.policy)) == sorted(
        (engine, policy) for engine in ("fast", "fast-step-api", "reference")
        for policy in (*MLPS, "nohold"))
    assert (df.decisions > df.episodes).all()
    np.testing.assert_allclose(df.episodes_per_cpu_second * df.cpu_seconds, df.episodes)
    np.testing.assert_allclose(df.decisions_per_second * df.wall_seconds, df.decisions)
    assert (df.policy_cpu_seconds < df.cpu_seconds).all()
    ref = df[df.engine == "reference"]
    np.testing.assert_allclose(ref[[c for c in df if c.endswith("speedup_vs_reference")]], 1.0)
    assert (tmp_path / "bench_bus.provenance.json").exists()
