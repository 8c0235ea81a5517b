"""Beyond the paper, X2 and X4: the race study in the wildfire simulator (beyond-races) and C9's
pair under both same-instant orders (beyond-order), their checks and their bad input."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from repro.claims import NOT_RUN, registry
from repro.cli import main
from repro.studies.races.wildfire_races import cell, crossing, fit
from repro.studies.transfer.order import studies
from repro.studies.transfer.study import TransferConfig
from tests.conftest import tree_snapshot, write_result_csv


def _main(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as exit_:  # argparse's errors
        return int(exit_.code)


def _claim(cid: str):
    return next(c for c in registry() if c.id == cid)


# --- X2: races ------------------------------------------------------------------------------------

@pytest.mark.slow
def test_beyond_races_smoke(cli, tmp_path):
    """The real entry point at smoke scale: every (policy, N, dT) cell, the columns other studies
    read, a fit row per (policy, N), the figure; ED-like dT has no race, dT = 10 s always."""
    res, fig = tmp_path / "r", tmp_path / "f"
    out = cli("beyond-races", "--scale", "smoke", "--results-dir", str(res), "--figures-dir",
              str(fig))
    assert out.returncode == 0, out.stderr
    t = pd.read_csv(res / "races.csv")
    assert {"policy", "n_agents", "n_clusters", "dt", "episodes", "p_race_episode",
            "p_race_ci_low", "p_race_ci_high", "races_per_decision"} <= set(t.columns)
    assert len(t) == 2 * 2 * 15 and set(t.policy) == {"nearest", "random"}
    assert (t.n_agents == t.n_clusters).all() and set(t.n_agents) == {3, 6}
    assert (t.p_race_ci_low <= t.p_race_episode).all()
    assert (t.p_race_episode <= t.p_race_ci_high).all()
    assert (t[t.dt == t.dt.min()].p_race_episode == 0).all()
    assert (t[t.dt == t.dt.max()].p_race_episode > 0.5).all()
    f = pd.read_csv(res / "races_fit.csv")
    assert len(f) == 4 and np.isfinite(f.dt_star).all()
    assert json.loads((res / "races.provenance.json").read_text())["scale"] == "smoke"
    assert (fig / "races.png").exists()


def test_a_race_cell_is_deterministic_and_its_draws_do_not_depend_on_dt():
    a, b = cell("nearest", 3, -2.0, 30, 5), cell("nearest", 3, -2.0, 30, 5)
    assert a == b and a["races"] > 0
    # the same episodes at every dT: a dT far below every gap gives the ED decisions' count
    fine, ed_like = cell("nearest", 3, -8.0, 30, 5), cell("nearest", 3, -7.5, 30, 5)
    assert fine["races"] == ed_like["races"] == 0 and fine["decisions"] == ed_like["decisions"]


def test_the_crossing_is_interpolated_in_log_dt():
    x = np.array([-3.0, -2.0, -1.0, 0.0])
    assert crossing(x, np.array([0.0, 0.05, 0.15, 1.0]), 0.1) == pytest.approx(-1.5)
    assert crossing(x, np.array([0.0, 0.1, 0.0, 1.0]), 0.1) == pytest.approx(-2.0)  # reached
    assert np.isnan(crossing(x, np.array([0.2, 0.3, 0.4, 1.0]), 0.1))  # below the grid
    assert np.isnan(crossing(x, np.array([0.0, 0.0, 0.01, 0.05]), 0.1))  # above it


def test_the_fit_recovers_a_known_exponent():
    """P(race) rises by 0.1 a decade and is 0.1 at dT* = N^-2: beta 2, alpha 1."""
    x = np.round(np.arange(-5, 0.01, 0.125), 9)
    rows = [dict(policy="nearest", n_agents=n, log10_dt=v,
                 p_race_episode=np.clip(0.1 * (1 + v + 2 * np.log10(n)), 0, 1))
            for n in (3, 6, 12, 24) for v in x]
    f = fit(pd.DataFrame(rows), 0.1, 2.2)
    assert f.beta.iloc[0] == pytest.approx(2.0, abs=1e-9) and f.alpha.iloc[0] == pytest.approx(1.0)
    assert f.beta_se.iloc[0] < 1e-9 and (f.n_fit == 4).all() and (f.c10_beta == 2.2).all()


def _x2_results(tmp_path, betas):
    cells = pd.DataFrame([dict(policy=p, n_agents=n, log10_dt=x, dt=10.0 ** x, episodes=100,
                               decisions=100 * n * 10) for p in betas for n in (3, 6)
                          for x in (-3.0, -2.0)])
    write_result_csv(cells, tmp_path / "races.csv")
    fits = pd.DataFrame([dict(policy=p, n_agents=n, dt_star=1e-3, delta=0.1, alpha=1.0, beta=b,
                              beta_se=0.1, n_fit=4, c10_beta=2.2)
                         for p, b in betas.items() for n in (3, 6)])
    write_result_csv(fits, tmp_path / "races_fit.csv")


def test_x2_check_can_pass_and_fail(tmp_path):
    x2 = _claim("X2")
    assert x2.evaluate(tmp_path).verdict == NOT_RUN
    write_result_csv(pd.DataFrame(dict(distribution=["e"], beta=[2.2])),
                     tmp_path / "table_race.csv")
    for betas, verdict in (({"nearest": 2.1, "random": 2.35}, "PASS"),
                           ({"nearest": 2.1, "random": 2.8}, "PARTIAL"),
                           ({"nearest": 1.7, "random": 2.8}, "FAIL"),
                           ({"nearest": 2.1, "random": float("nan")}, NOT_RUN)):
        _x2_results(tmp_path, betas)
        v = x2.evaluate(tmp_path)
        assert v.verdict == verdict, v
        assert verdict == NOT_RUN or "nearest 1.00" in v.detail  # decisions grow as N


@pytest.mark.parametrize("argv, param", [
    (["--episodes", "0"], "--episodes"), (["--n-agents", "3"], "--n-agents"),
    (["--n-agents", "0", "--n-agents", "3"], "--n-agents"), (["--policy", "greedy"], "--policy"),
    (["--log10-dt-min", "1"], "--log10-dt-min"), (["--log10-dt-min", "-12"], "--log10-dt-min"),
    (["--log10-dt-step", "0"], "--log10-dt-step"), (["--delta", "1.5"], "--delta"),
    (["--n-jobs", "0"], "--n-jobs"), (["--scale", "huge"], "--scale"), (["--seed", "-1"], "--seed"),
    (["--episodes", "x"], "--episodes")])
def test_beyond_races_bad_input_is_one_line_and_writes_nothing(tmp_path, monkeypatch, capsys,
                                                               argv, param):
    monkeypatch.chdir(tmp_path)
    assert _main(["beyond-races", *argv]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1 and param in err, err
    assert list(tmp_path.iterdir()) == []


# --- X4: the same-instant order ------------------------------------------------------------------

def test_the_order_studies_are_c9s_pair_with_the_transfer_studys_names():
    plan = studies(TransferConfig())
    assert [(s, o, c.name) for s, o, c in plan] == [
        ("released", "released", "transfer"),
        ("released", "reversed", "transfer_no_fire_out_first"),
        ("released, Q3 off", "released", "transfer_no_q3"),
        ("released, Q3 off", "reversed", "transfer_no_q3_no_fire_out_first")]
    for _, order, cfg in plan:
        sims = [*cfg.simulators().values(), cfg.test_simulator()]
        assert list(cfg.simulators()) == ["FS-1", "FS-1 (T_health=2.9999)"]
        assert all(s.fire_out_first == (order == "released") for s in sims)


def test_beyond_order_reuses_the_transfer_studys_runs(tmp_path, monkeypatch):
    """The released-order runs are fig-transfer's: a finished fig-transfer (Q3 off, C9's pair)
    is not retrained and its policies score as there; a second run rewrites the same CSVs."""
    monkeypatch.setenv("REPRO_QUIET", "1")
    common = ["--scale", "smoke", "--test-episodes", "5", "--n-jobs", "1", "--runs-dir",
              str(tmp_path / "runs"), "--figures-dir", str(tmp_path / "fig")]
    assert _main(["fig-transfer", *common, "--no-quirk", "q3", "--simulator", "FS-1",
                  "--simulator", "FS-1 (T_health=2.9999)", "--results-dir",
                  str(tmp_path / "t")]) == 0
    done = tree_snapshot(tmp_path / "runs")
    outs = []
    for i in range(2):
        assert _main(["beyond-order", *common, "--results-dir", str(tmp_path / f"r{i}")]) == 0
        outs.append([(tmp_path / f"r{i}" / f"order_reversal{s}.csv").read_bytes()
                     for s in ("", "_summary", "_effect")])
    assert outs[0] == outs[1]
    after = tree_snapshot(tmp_path / "runs")
    assert all(after[k] == v for k, v in done.items())  # not retrained
    assert len({k.split("/runs/")[1].split("/")[0] for k in after}) == 4  # four studies
    ours = pd.read_csv(tmp_path / "r0" / "order_reversal.csv")
    theirs = pd.read_csv(tmp_path / "t" / "transfer_no_q3.csv")
    mine = ours[(ours.semantics == "released, Q3 off") & (ours.order == "released")]
    np.testing.assert_array_equal(mine.adr_ed, theirs.adr_ed)
    effect = pd.read_csv(tmp_path / "r0" / "order_reversal_effect.csv")
    assert len(effect) == 4 and (effect.n_policies == 1).all()
    assert (tmp_path / "fig" / "order_reversal.png").exists()


def _x4_results(tmp_path, degrades: dict[tuple[str, str], bool], n: int = 5):
    rows = [dict(semantics=s, order=o, n_policies=n, adr_variant=2.0 if d else 2.9, adr_fs=2.95,
                 difference=-0.95 if d else -0.05, ci_low=-1.2 if d else -0.1,
                 ci_high=-0.7 if d else 0.02, degrades=d) for (s, o), d in degrades.items()]
    write_result_csv(pd.DataFrame(rows), tmp_path / "order_reversal_effect.csv")


@pytest.mark.parametrize("q3_off_reversed, n, verdict", [
    (True, 5, "PASS"), (False, 5, "FAIL"), (True, 1, "PARTIAL")])
def test_x4_check(tmp_path, q3_off_reversed, n, verdict, stored_intervals):
    x4 = _claim("X4")
    assert x4.evaluate(tmp_path).verdict == NOT_RUN
    _x4_results(tmp_path, {("released", "released"): False, ("released", "reversed"): False,
                           ("released, Q3 off", "released"): True,
                           ("released, Q3 off", "reversed"): q3_off_reversed}, n)
    v = x4.evaluate(tmp_path)
    assert v.verdict == verdict, v
    assert "degrades in: released, Q3 off" in v.detail
    assert "Only the reversed order" not in v.detail


def test_x4_says_where_only_the_reversed_order_degrades(tmp_path, stored_intervals):
    _x4_results(tmp_path, {("released", "released"): False, ("released", "reversed"): True,
                           ("released, Q3 off", "released"): True,
                           ("released, Q3 off", "reversed"): True})
    v = _claim("X4").evaluate(tmp_path)
    assert v.verdict == "PASS"
    assert "Only the reversed order degrades in: released:" in v.detail


@pytest.mark.parametrize("command, argv, param", [
    ("beyond-order", ["--seeds", "0"], "--seeds"),
    ("beyond-order", ["--test-episodes", "0"], "--test-episodes"),
    ("beyond-order", ["--n-jobs", "0"], "--n-jobs"),
    ("beyond-order", ["--scale", "huge"], "--scale"),
    ("beyond-order", ["--scheduler", "notanaddress", "--scale", "smoke"], "--scheduler"),
    ("fig-transfer", ["--no-fire-out-first=yes"], "--no-fire-out-first"),
    ("train", ["--env", "wildfire", "--no-fire-out-first", "--same-instant-order", "scheduling",
               "--out", "run"], "--no-fire-out-first"),
    ("train", ["--env", "wildfire", "--fire-out-first=no", "--out", "run"], "--fire-out-first"),
])
def test_order_bad_input_is_one_line_and_writes_nothing(tmp_path, monkeypatch, capsys, command,
                                                        argv, param):
    monkeypatch.chdir(tmp_path)
    assert _main([command, *argv]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1 and param in err, err
    assert list(tmp_path.iterdir()) == []
