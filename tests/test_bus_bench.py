"""bench-bus at smoke scale: one row per engine and policy, rates consistent with the times."""

from __future__ import annotations

import pandas as pd

from repro.cli import main


def test_bench_bus_smoke(tmp_path):
    assert main(["bench-bus", "--scale", "smoke", "--results-dir", str(tmp_path)]) == 0
    df = pd.read_csv(tmp_path / "bench_bus.csv")
    assert sorted(zip(df.policy, df.engine)) == [("mlp", "fast"), ("mlp", "simpy"),
                                                 ("nohold", "fast"), ("nohold", "simpy")]
    assert (df.decisions > df.episodes).all()
    pd.testing.assert_series_equal(df.episodes_per_s, df.episodes / df.cpu_seconds,
                                   check_names=False)
    assert (df.policy_cpu_seconds < df.cpu_seconds).all()
    assert (df[df.engine == "simpy"].speedup_vs_simpy == 1.0).all()
    assert (tmp_path / "bench_bus.provenance.json").exists()
