"""An option the chosen policy does not use is refused (one line naming it and when it is used,
exit status 2, nothing written), so that a command line never says more than what runs."""

import pytest

from repro.cli import main
from tests.conftest import tree_snapshot

PICTURE = ["--results-dir", "r", "--figures-dir", "f"]


@pytest.mark.parametrize("argv, param, when", [
    (["bus-eval", "--policy", "thresholds", "--mlp-run", "X"], "--mlp-run", "--policy mlp"),
    (["bus-eval", "--policy", "nohold", "--thresholds", "1", "2", "3"], "--thresholds",
     "--policy thresholds"),
    (["bus-eval", "--policy", "mlp", "--gru-run", "X"], "--gru-run", "--policy gru"),
    (["bus-eval", "--policy", "authors", "--learner", "suite"], "--learner", "without --mlp-run"),
    (["bus-eval", "--policy", "mlp", "--mlp-run", "X", "--learner", "suite"], "--learner",
     "without --mlp-run"),
    (["bus-eval", "--policy", "nohold", "--results-dir", "r"], "--results-dir",
     "without --thresholds"),
    (["bus-eval", "--policy", "thresholds", "--thresholds", "1", "2", "3", "--results-dir", "r"],
     "--results-dir", "without --thresholds"),
    (["bus-arrivals", "--policies", "nohold", "--mlp-run", "X", *PICTURE], "--mlp-run",
     "an mlp panel"),
    (["bus-loads", "--policies", "nohold", "authors", "--thresholds", "1", "2", "3", *PICTURE],
     "--thresholds", "a thresholds panel"),
    (["bus-arrivals", "--policies", "nohold", "--gru-run", "X", *PICTURE], "--gru-run",
     "a gru panel"),
    (["bus-loads", "--policies", "nohold", "mlp", "--n-jobs", "2", *PICTURE], "--n-jobs",
     "without --gru-run"),
    (["bus-arrivals", "--policies", "gru", "--gru-run", "X", "--scheduler", "tcp://h:1",
      *PICTURE], "--scheduler", "without --gru-run"),
    (["render", "--env", "bus", "--policy", "authors", "--results-dir", "r", "--out", "a.gif"],
     "--results-dir", "thresholds"),
    (["render", "--env", "bus", "--policy", "mlp", "RUN", "--results-dir", "r", "--out", "a.gif"],
     "--results-dir", "without a RUN"),
    (["render", "--env", "wildfire", "--policy", "nearest", "--results-dir", "r", "--out",
      "a.gif"], "--results-dir", "thresholds"),
])
def test_an_option_the_policy_does_not_use_is_refused(tmp_path, monkeypatch, capsys, argv,
                                                      param, when):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"error: {param}: must be given only" in err and when in err, err
    assert tree_snapshot(tmp_path) == {} and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv, param", [
    # each option where its policy uses it: refused later, for what it names, not as unused
    (["bus-eval", "--policy", "mlp", "--learner", "suite", "--results-dir", "r"], "--mlp-run"),
    (["bus-eval", "--policy", "thresholds", "--results-dir", "r"], "--thresholds"),
    (["bus-eval", "--policy", "gru-greedy", "--gru-run", "X"], "--gru-run"),
    (["render", "--env", "bus", "--policy", "thresholds", "--results-dir", "r", "--out",
      "a.gif"], "--results-dir"),
    (["render", "--env", "bus", "--policy", "checkpoint", "X", "--seed", "3", "--out", "a.gif"],
     "--policy"),
])
def test_an_option_its_policy_uses_is_taken(tmp_path, monkeypatch, capsys, argv, param):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert f"error: {param}: " in err and "given only" not in err, err
    assert list(tmp_path.iterdir()) == []


def test_render_takes_the_gru_policies_with_their_run(tmp_path, monkeypatch, capsys):
    """render's bus gru policies name their run after the name, as mlp does (the refusal named
    --gru-run, an option render does not have)."""
    monkeypatch.chdir(tmp_path)
    for argv, got in ((["gru-greedy"], "'gru-greedy'"), (["gru", "X"], "X/checkpoint.pt")):
        assert main(["render", "--env", "bus", "--policy", *argv, "--out", "a.gif"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("repro render: error: --policy: must be ") and got in err, err
    assert list(tmp_path.iterdir()) == []
