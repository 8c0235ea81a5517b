"""The bus training sweeps end to end at smoke scale: outputs, orderings a short run can show,
resumption with byte-identical CSVs, the trained-MLP figure panels, the claim checks, bad input."""

from __future__ import annotations

import subprocess
import sys

import pandas as pd
import pytest

from repro.claims import VERDICTS
from repro.claims.bus import check_c1, check_c2, check_c3, check_c5
from repro.cli import main
from tests.conftest import write_result_csv

pytestmark = pytest.mark.slow  # studies end to end, subprocesses: left out of make test-fast


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory):
    res, fig, runs = (tmp_path_factory.mktemp(n) for n in ("res", "fig", "runs"))
    common = ["--scale", "smoke", "--results-dir", str(res), "--figures-dir", str(fig)]
    sweep = [*common, "--runs-dir", str(runs), "--n-jobs", "1", "--seeds", "1"]
    assert main(["bus-thresholds", "--scale", "smoke", "--results-dir", str(res)]) == 0
    assert main(["fig-bus-lambda", *sweep]) == 0
    assert main(["fig-bus-batch", *sweep]) == 0
    for cmd in ("fig-bus-arrivals", "fig-bus-load"):
        assert main([cmd, *common]) == 0
    return res, fig, sweep


def test_outputs(sweeps):
    res, fig, _ = sweeps
    table = pd.read_csv(res / "bus_lambda.csv")
    assert list(table.columns) == ["lambda", "batch", "seed", "epoch", "average_return",
                                   "average_discounted_return"]
    assert sorted(table["lambda"].unique()) == [1.0, 2.0, 4.0, 8.0]  # the released runner's
    assert sorted(pd.read_csv(res / "bus_batch.csv").batch.unique()) == [6, 12, 24]
    for stem in ("bus_lambda", "bus_batch"):
        assert (fig / f"{stem}.png").exists() and (fig / f"{stem}.pdf").exists()
        assert (res / f"{stem}_summary.provenance.json").exists()
    every = {"nohold", "authors", "mlp", "thresholds"}
    assert set(pd.read_csv(res / "bus_arrivals.csv").policy) == every
    assert set(pd.read_csv(res / "bus_load.csv").policy) == every
    mlp_runs = pd.read_csv(res / "bus_load_mlp_runs.csv")
    assert sorted(mlp_runs["lambda"]) == [1.0, 2.0, 4.0, 8.0] and (mlp_runs.seed == 0).all()
    assert (mlp_runs.l1_per_point > 0).all()  # a smoke-trained MLP is not the paper's


def test_mlp_run_of_other_switches_is_refused(sweeps, capsys, tmp_path):
    """The sweep trained the released semantics: a corrected figure cannot show its MLP, named
    or as the best run of the corrected sweep, which has not run."""
    res, _, _ = sweeps
    before = sorted(p.name for p in res.iterdir())
    released = pd.read_csv(res / "bus_lambda_summary.csv").dropna(subset=["run"]).run.iloc[0]
    for named in (["--mlp-run", released], []):
        assert main(["fig-bus-load", "--results-dir", str(res), "--figures-dir", str(tmp_path),
                     "--policies", "mlp", "--corrected", *named]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1, err
        if named:
            assert "--mlp-run: must be a run trained with this command's switches" in err[0]
            assert "b1_reward" in err[0]
        else:
            assert str(res / "corrected") in err[0], err
    assert sorted(p.name for p in res.iterdir()) == before and not any(tmp_path.rglob("*.*"))


def test_runs_from_before_the_switches_count_as_corrected(tmp_path):
    """A run folder whose config.json predates B1-B5 holds a corrected run, not a released one."""
    import json

    from repro.core.config import to_dict
    from repro.core.errors import UsageError
    from repro.envs.bus import BusConfig
    from repro.learn.config import TrainConfig
    from repro.learn.run_identity import check_run_folder, run_config
    saved = run_config(TrainConfig(), BusConfig.corrected(), "bus")
    for name in ("b1_reward", "b2_headway", "b3_boarding", "b4_round_half_even", "b5_timing"):
        del saved["env"][name]
    (tmp_path / "config.json").write_text(json.dumps(saved, default=str))
    check_run_folder(tmp_path, TrainConfig(), BusConfig.corrected(), "bus")
    with pytest.raises(UsageError, match="env.b1_reward: False there, True here"):
        check_run_folder(tmp_path, TrainConfig(), BusConfig(), "bus")
    assert to_dict(BusConfig())["b1_reward"] is True


def test_orderings_a_short_run_shows(sweeps):
    """Optimized Thresholds above No Holding; the trained policy above No Holding and above where
    it started (a random policy already edges No Holding, so that alone would prove nothing)."""
    res = sweeps[0]
    summary = pd.read_csv(res / "bus_lambda_summary.csv")
    base = summary.set_index("policy").final_iqm
    assert base["thresholds"] > base["nohold"]
    curve = pd.read_csv(res / "bus_lambda.csv").query("`lambda` == 2.0")
    mlp = summary[(summary.policy == "mlp") & (summary["lambda"] == 2.0)].final_iqm.iloc[0]
    assert mlp > base["nohold"]
    assert curve.average_return.iloc[-1] > curve.average_return.iloc[0]


def test_rerun_skips_finished_runs_and_rewrites_identically(sweeps):
    res, _, sweep = sweeps
    before = (res / "bus_batch.csv").read_bytes()
    assert main(["fig-bus-batch", *sweep]) == 0
    assert (res / "bus_batch.csv").read_bytes() == before


def test_claim_checks_give_verdicts(sweeps):
    res = sweeps[0]
    for check in (check_c1, check_c2, check_c3, check_c5):
        v = check(res)
        assert v.verdict in VERDICTS and v.scale == "smoke" and v.ours


def _write_summary(res, sweep: str, settings: dict[float, list[float]], thresholds: float,
                   nohold: float = -90000.0) -> None:
    """A sweep summary like the drivers write: per setting its runs' final returns, their IQM and a
    CI spanning them, and the two exact baselines."""
    key = "lambda" if sweep == "lambda" else "batch"
    rows = [dict(policy=p, runs=1, final_iqm=v, ci_low=v, ci_high=v)
            for p, v in (("nohold", nohold), ("thresholds", thresholds))]
    for setting, finals in settings.items():
        rows.append(dict(policy="mlp", runs=len(finals), final_iqm=float(pd.Series(finals).mean()),
                         ci_low=min(finals), ci_high=max(finals), **{key: setting}))
        rows += [dict(policy="mlp-run", runs=1, final_iqm=v, ci_low=v, ci_high=v, **{key: setting})
                 for v in finals]
    write_result_csv(pd.DataFrame(rows), res / f"bus_{sweep}_summary.csv")


@pytest.mark.parametrize("mlp, thresholds, verdict", [
    ([-100.0, -99.0, -98.0], -200.0, "PASS"),      # MLP's whole interval above thresholds
    ([-300.0, -100.0, -99.0], -200.0, "PARTIAL"),  # only the point estimate above
    ([-300.0, -299.0, -298.0], -200.0, "FAIL"),
    ([-100.0, -99.0, -98.0], -95000.0, "FAIL"),    # thresholds below No Holding
])
def test_c1_verdict_follows_the_orderings(tmp_path, stored_intervals, mlp, thresholds, verdict):
    _write_summary(tmp_path, "lambda", {2.0: mlp}, thresholds)
    assert check_c1(tmp_path).verdict == verdict


@pytest.mark.parametrize("settings, verdict", [
    ({0.5: [-101.0, -100.0, -99.0], 2.0: [-100.0, -99.0, -98.0]}, "PASS"),  # spread ~1, gap ~100
    ({0.5: [-190.0, -189.0, -188.0], 2.0: [-100.0, -99.0, -98.0]}, "FAIL"),  # spread 90, gap 56
])
def test_c2_verdict_compares_the_spread_over_lambda_with_the_gap(tmp_path, stored_intervals,
                                                                 settings, verdict):
    _write_summary(tmp_path, "lambda", settings, thresholds=-200.0)
    assert check_c2(tmp_path).verdict == verdict


def _write_curves(res, early: dict[int, list[float]], final: float, epochs: int = 6) -> None:
    """A batch sweep's per-epoch table: each run at its early level for the first half of its
    epochs, then at ``final``; the sidecar records the epochs the reading takes."""
    rows = [dict(batch=b, seed=s, epoch=e, average_return=level if e < epochs // 2 else final,
                 average_discounted_return=0.0, **{"lambda": 2.0})
            for b, levels in early.items() for s, level in enumerate(levels)
            for e in range(epochs)]
    write_result_csv(pd.DataFrame(rows), res / "bus_batch.csv",
                     config=dict(epochs=epochs, final_epochs=2, early_epochs=epochs // 2))


@pytest.mark.parametrize("means, verdict", [
    ((-300.0, -200.0, -100.0), "PASS"),     # monotone, ends separated
    ((-300.0, -50.0, -100.0), "PARTIAL"),   # not monotone, but the largest beats the smallest
    ((-100.0, -200.0, -300.0), "FAIL"),
])
def test_c3_verdict_reads_convergence_over_the_run(tmp_path, stored_intervals, means, verdict):
    """C3 reads the early return (the first early_epochs), not the final level: every run here
    ends at one level."""
    early = {b: [m - 1.0, m, m + 1.0] for b, m in zip((54, 135, 540), means)}
    _write_summary(tmp_path, "batch", {b: [-150.0] * 3 for b in early}, thresholds=-120.0)
    _write_curves(tmp_path, early, final=-150.0)
    v = check_c3(tmp_path)
    assert v.verdict == verdict
    assert "thresholds reached by 0/3" in v.ours or "thresholds reached by 3/3" in v.ours


def test_pool_sweep(tmp_path):
    """The batch sweep on the released pool: its own files and run folders, the batches'
    distinct episodes in the table, the convergence readings; refused for the suite's learner."""
    res, runs = tmp_path / "res", tmp_path / "runs"
    assert main(["bus-thresholds", "--scale", "smoke", "--results-dir", str(res)]) == 0
    args = ["fig-bus-batch", "--sampler", "released-pool", "--scale", "smoke", "--results-dir",
            str(res), "--figures-dir", str(tmp_path / "fig"), "--runs-dir", str(runs),
            "--n-jobs", "1", "--seeds", "1"]
    assert main(args) == 0
    table = pd.read_csv(res / "bus_batch_pool.csv")
    assert (table.distinct_episodes >= 1).all()
    assert (table.distinct_episodes <= 4).all()  # the smoke learner's 4 workers
    read = pd.read_csv(res / "bus_batch_pool_convergence.csv")
    assert list(read.columns) == ["lambda", "batch", "seed", "early_return",
                                  "epochs_to_thresholds", "final_return"]
    assert sorted(p.name for p in (runs / "bus-released").iterdir() if p.is_dir()) == [
        f"pool_lam2_dec{b}_seed0" for b in (12, 24, 6)]
    assert (tmp_path / "fig" / "bus_batch_pool.png").exists()
    assert not (res / "bus_batch.csv").exists()
    assert main([*args, "--learner", "suite"]) == 2


@pytest.mark.parametrize("args", [
    ["fig-bus-lambda", "--seeds", "0"],
    ["fig-bus-batch", "--epochs", "2", "--final-epochs", "3"],
    ["fig-bus-lambda", "--n-jobs", "0"],
    ["fig-bus-batch", "--sampler", "shared"],
    ["fig-bus-batch", "--early-epochs", "0"],
    ["fig-bus-lambda"],  # no results/bus_thresholds.csv yet
    ["fig-bus-arrivals", "--policies", "mlp"],  # no lambda sweep yet
])
def test_bad_input(args, tmp_path):
    proc = subprocess.run([sys.executable, "-m", "repro", *args, "--scale", "smoke",
                           "--results-dir", str(tmp_path / "r"), "--figures-dir",
                           str(tmp_path / "f"), *(["--runs-dir", str(tmp_path / "runs")]
                                                  if "arrivals" not in args[0] else [])],
                          capture_output=True, text=True)
    assert proc.returncode == 2, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())
