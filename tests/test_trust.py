"""Nothing hangs, nothing crashes on a refusal, nothing half-trusted is used: the scheduler
address, refusals from worker processes, results folders and their pairs, damaged checkpoints,
sizes and paths."""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import shutil
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pandas as pd
import pytest
import torch

from repro.claims import NOT_RUN, registry
from repro.cli import main
from repro.core.errors import UsageError, require
from repro.core.rollout import rollout_bytes
from repro.learn.trained_policy import policy_from_checkpoint
from repro.runs import memory
from repro.runs import results as results_module
from repro.runs.locks import folder_lock
from repro.runs.results import (CSV_HASH, RESULTS_LOCK, csv_bytes, read_provenance, read_result,
                                sidecar_path, write_result)
from repro.runs.run_folder import (CHECKPOINT, load_checkpoint, save_checkpoint, state_problem,
                                   writer_lock)
from repro.studies.kit import sweep
from repro.studies.kit.options import Workers
from tests.conftest import ROOT, tree_snapshot, write_result_csv


@pytest.fixture(autouse=True)
def quiet(monkeypatch):
    """No progress bars on stderr, where each refusal is checked to be one line."""
    monkeypatch.setenv("REPRO_QUIET", "1")


def _main(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as exit_:  # argparse's errors
        return int(exit_.code)


def _one_line(capsys, param: str) -> str:
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and param in lines[0], err
    return lines[0]


# --- the scheduler address -----------------------------------------------------------------------

@pytest.mark.parametrize("address", ["notanaddress", "tcp://host", "tcp://host:0",
                                     "tcp://host:99999", "http://host:80", "tcp://a b:1", "",
                                     "inproc://x", "tcp://:8786"])
def test_a_malformed_scheduler_address_is_refused_before_any_connection(address, monkeypatch):
    def no_lookup(*args, **kwargs):
        raise AssertionError("looked up")

    monkeypatch.setattr(socket, "getaddrinfo", no_lookup)
    with pytest.raises(UsageError, match="--scheduler"):
        sweep._dask_client(address)


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:8786", "tls://sched.example.org:8786",
                                     "127.0.0.1:1", "tcp://[::1]:8786"])
def test_well_formed_scheduler_addresses(address):
    assert sweep.check_scheduler(address)[2] >= 1


class Listener:
    """A TCP listener on loopback that is not Dask: it says nothing (``reply`` None) or answers
    any bytes with ``reply`` and closes."""

    def __init__(self, reply: bytes | None):
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.address = f"tcp://127.0.0.1:{self.sock.getsockname()[1]}"
        self.reply, self.held = reply, []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.held.append(conn)
            if self.reply is not None:
                conn.recv(64)
                conn.sendall(self.reply)
                conn.close()

    def close(self) -> None:
        self.sock.close()
        for conn in self.held:
            conn.close()


@pytest.mark.parametrize("reply", [None, b"HTTP/1.0 400 Bad request\r\n\r\n<html></html>"])
def test_a_listener_that_is_not_dask_is_refused_within_the_deadline(reply, monkeypatch, tmp_path,
                                                                      capsys):
    """A silent listener (the Dask client's own timeout does not end that wait) and a web server
    are both refused in one line, exit 2, once the deadline has passed, before anything trains."""
    monkeypatch.setattr(sweep, "SCHEDULER_DEADLINE", 0.5)
    listener = Listener(reply)
    try:
        t0 = time.perf_counter()
        assert _main(["fig-transfer", "--scale", "smoke", "--simulator", "ED",
                      "--scheduler", listener.address, "--runs-dir", str(tmp_path / "runs"),
                      "--results-dir", str(tmp_path / "res"),
                      "--figures-dir", str(tmp_path / "fig")]) == 2
        assert time.perf_counter() - t0 < 10
    finally:
        listener.close()
    _one_line(capsys, "--scheduler")
    assert list(tmp_path.iterdir()) == []  # no folder of runs, results or figures, no lock


# --- refusals across processes -------------------------------------------------------------------

def test_a_refusal_pickles_as_itself():
    err = pickle.loads(pickle.dumps(UsageError("--runs-dir", "x", "/x")))
    assert type(err) is UsageError and str(err) == "--runs-dir: must be x, got '/x'"
    assert (err.param, err.allowed, err.got) == ("--runs-dir", "x", "/x")


def test_a_refusal_in_a_worker_process_reaches_the_caller_intact():
    with pytest.raises(UsageError) as caught:
        sweep.map_tasks(require, [(True, "--a", "b"), (False, "--runs-dir", "free", "/r")],
                        Workers(n_jobs=2))
    assert str(caught.value) == "--runs-dir: must be free, got '/r'"


def _transfer(tmp_path, *more: str) -> list[str]:
    return ["fig-transfer", "--scale", "smoke", "--simulator", "ED", "--test-episodes", "5",
            "--runs-dir", str(tmp_path / "runs"), "--results-dir", str(tmp_path / "res"),
            "--figures-dir", str(tmp_path / "fig"), *more]


def test_a_sweep_meeting_a_run_folder_in_use_is_refused_naming_runs_dir(tmp_path, capsys,
                                                                         monkeypatch):
    """Two jobs pending, one of them being written by another process: one line naming
    --runs-dir, exit 2, and nothing trained."""
    root = tmp_path / "runs" / "transfer" / "smoke"
    with writer_lock(root / "ed-th3-seed1"):
        assert _main(_transfer(tmp_path, "--seeds", "2", "--n-jobs", "2")) == 2
    line = _one_line(capsys, "--runs-dir")
    assert "ed-th3-seed1" in line and "pid" in line
    assert not (root / "ed-th3-seed0").exists() and not (tmp_path / "res").exists()


def test_a_second_sweep_over_the_same_runs_is_refused_naming_runs_dir(tmp_path, capsys,
                                                                      monkeypatch):
    root = tmp_path / "runs" / "transfer" / "smoke"
    with folder_lock(root, sweep.SWEEP_LOCK, "--runs-dir", "a folder of runs"):
        assert _main(_transfer(tmp_path, "--n-jobs", "2")) == 2
    assert "sweep.lock" in _one_line(capsys, "--runs-dir")
    assert not root.exists()  # nothing written: gone with the lock that made it


# --- results folders and their pairs -------------------------------------------------------------

def _pair(folder, name="t.csv", scale="smoke", overwrite=False):
    return write_result(folder / name, pd.DataFrame(dict(x=[1.0])), {"scale": scale},
                        overwrite=overwrite)


def test_a_sidecar_records_its_csv_and_a_pair_that_does_not_match_reads_not_yet_run(tmp_path):
    path = _pair(tmp_path, "table_race.csv")
    side = json.loads(sidecar_path(path).read_text())
    assert side[CSV_HASH] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert path.read_bytes() == csv_bytes(pd.DataFrame(dict(x=[1.0])))  # the CSV as before
    assert read_result(path).x.tolist() == [1.0]
    path.write_text("x\n2\n")  # another writer's CSV (or a hand edit) beside this sidecar
    with pytest.raises(FileNotFoundError):
        read_result(path)
    c10 = next(c for c in registry() if c.id == "C10")
    assert c10.evaluate(tmp_path).verdict == NOT_RUN


def test_a_sidecar_without_a_hash_is_taken_as_it_is(tmp_path):
    """The committed results' sidecars were written before the hash: they stay readable."""
    write_result_csv(pd.DataFrame(dict(x=[3])), tmp_path / "old.csv")
    assert CSV_HASH not in read_provenance(tmp_path / "old.csv")
    assert read_result(tmp_path / "old.csv").x.tolist() == [3]


def test_a_csv_without_a_sidecar_waits_for_one_only_while_its_folder_is_being_written(
        tmp_path, monkeypatch):
    """A reader gives a writer at work (old sidecar removed, CSV and sidecar still to come) a
    moment; a folder that nobody changed for longer holds a result that is simply not yet run,
    read so at once (the claims read such files a hundred times)."""
    path = tmp_path / "t.csv"
    path.write_text("x\n1\n")
    naps = []
    monkeypatch.setattr(results_module.time, "sleep", naps.append)
    with pytest.raises(FileNotFoundError):
        read_result(path)
    assert naps  # just written: waited
    old = time.time() - 2 * results_module.WRITER_MOMENT
    for changed in (path, tmp_path):
        os.utime(changed, (old, old))
    naps.clear()
    with pytest.raises(FileNotFoundError):
        read_result(path)
    assert naps == []


WRITER = """
import sys
import pandas as pd
from pathlib import Path
from repro.runs.results import write_result
folder, me = Path(sys.argv[1]), int(sys.argv[2])
for i in range(60):
    write_result(folder / f"slot{i % 6}.csv", pd.DataFrame(dict(writer=[me] * 50, i=range(50))),
                 {"scale": "smoke", "writer": me})
"""


def test_two_writers_never_leave_a_torn_pair_and_a_reader_never_takes_one(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    writers = [subprocess.Popen([sys.executable, "-c", WRITER, str(tmp_path), str(k)], env=env)
               for k in (1, 2)]
    reads = torn = 0
    while any(w.poll() is None for w in writers):
        for i in range(6):
            try:
                table = read_result(tmp_path / f"slot{i}.csv")
            except FileNotFoundError:
                torn += 1  # not yet written, or a pair being written: "not yet run"
                continue
            reads += 1
            assert len(set(table.writer)) == 1 and len(table) == 50
    assert [w.wait(timeout=60) for w in writers] == [0, 0]
    for i in range(6):
        path = tmp_path / f"slot{i}.csv"
        prov = read_provenance(path)
        assert prov[CSV_HASH] == hashlib.sha256(path.read_bytes()).hexdigest()
        assert read_result(path).writer.iloc[0] == prov["writer"]
    pairs = sorted(p.name for p in tmp_path.iterdir() if ".recreated-" not in p.name)
    assert reads > 0 and pairs == sorted(
        [f"slot{i}.csv" for i in range(6)] + [f"slot{i}.provenance.json" for i in range(6)])
    for note in tmp_path.glob("*.recreated-*.json"):  # a writer making its own bytes again
        assert json.loads(note.read_text())["recreates"] in pairs


RACE = ("race", "--scale", "smoke", "--n-sets", "400", "--n-max", "5", "--distribution",
        "exponential", "--no-figure")


def test_a_second_writer_of_a_results_folder_is_refused(tmp_path, capsys):
    with folder_lock(tmp_path / "res", RESULTS_LOCK, "--results-dir", "a results folder"):
        assert _main([*RACE, "--results-dir", str(tmp_path / "res")]) == 2
    assert RESULTS_LOCK in _one_line(capsys, "--results-dir")
    assert not (tmp_path / "res").exists()  # nothing written: gone with the lock that made it


def test_results_of_a_larger_scale_are_replaced_only_when_told(tmp_path, capsys):
    """Committed paper-scale results in the folder a smoke run names: refused before any work,
    nothing changed; --overwrite replaces them. The guard is the sidecars' scale, whatever the
    folder is called."""
    res, fig = tmp_path / "anywhere", tmp_path / "fig"
    res.mkdir()
    for name in ("table_race", "race_exact"):
        for ext in (".csv", ".provenance.json"):
            shutil.copy(ROOT / "results" / "paper" / (name + ext), res)
    before = tree_snapshot(res)
    assert _main([*RACE[:-1], "--results-dir", str(res), "--figures-dir", str(fig)]) == 2
    line = _one_line(capsys, "--results-dir")
    assert "paper" in line and "--overwrite" in line
    assert tree_snapshot(res) == before and not fig.exists()
    with pytest.raises(UsageError, match="--results-dir"):  # a pair written outside a driver
        _pair(res, "table_race.csv", scale="quick")
    assert tree_snapshot(res) == before
    assert _main([*RACE, "--results-dir", str(res), "--overwrite"]) == 0
    assert read_provenance(res / "table_race.csv")["scale"] == "smoke"
    assert not (res / RESULTS_LOCK).exists()


PAPER_BUT = ("race", "--scale", "paper", "--n-sets", "10", "--exact-n", "2", "3",
             "--bisection-steps", "3", "--distributions", "exponential", "--no-figure")
"""A run asked at the paper scale with settings of its own."""


def test_a_paper_scale_run_with_settings_of_its_own_is_no_paper_scale_run(tmp_path, capsys):
    """It does not replace paper-scale results (refused before any work, naming the settings
    that differ), and where it writes, its sidecars record the scale "custom" and why."""
    res = tmp_path / "paper"
    res.mkdir()
    for name in ("table_race", "race_exact"):
        for ext in (".csv", ".provenance.json"):
            shutil.copy(ROOT / "results" / "paper" / (name + ext), res)
    before = tree_snapshot(res)
    assert _main([*PAPER_BUT, "--results-dir", str(res)]) == 2
    line = _one_line(capsys, "--results-dir")
    assert "custom: --n-sets, --distributions, --bisection-steps, --exact-n differ" in line
    assert tree_snapshot(res) == before
    assert _main([*PAPER_BUT, "--results-dir", str(tmp_path / "elsewhere")]) == 0
    prov = read_provenance(tmp_path / "elsewhere" / "table_race.csv")
    assert prov["scale"] == "custom" and prov["departs_from_scale"] == {
        "scale": "paper", "options": ["--n-sets", "--distributions", "--bisection-steps",
                                      "--exact-n"]}


def _departures(command: str, *argv: str) -> list[str]:
    import importlib

    from repro.cli import ALIASES, COMMANDS, OneLineParser
    from repro.studies.kit.options import scale_departures

    module = importlib.import_module(COMMANDS[ALIASES.get(command, command)][0])
    parser = OneLineParser(prog=command)
    module.add_arguments(parser)
    return scale_departures(parser, parser.parse_args(argv), getattr(module, "VARIANTS", ()))


def test_the_settings_of_a_run_are_compared_with_its_scales():
    """A flag given with the scale's own value, or one that chooses another study (its own
    result files), leaves a run at its scale; a subset of the study's simulators does not."""
    from repro.studies.races.race import RaceConfig

    paper_sets = str(RaceConfig.SCALES["paper"].get("n_sets", RaceConfig.n_sets))
    assert _departures("race", "--scale", "paper", "--n-sets", paper_sets) == []
    assert _departures("race", "--scale", "paper", "--n-sets", "10") == ["--n-sets"]
    assert _departures("fig-transfer", "--scale", "paper", "--sim-version", "2017-04-22",
                       "--learner", "suite", "--n-jobs", "2", "--seed", "0") == []
    assert _departures("fig-transfer", "--scale", "paper", "--sampler", "released-pool") == []
    assert _departures("fig-transfer", "--scale", "paper", "--simulator", "ED") == ["--only"]
    # a command's own default of a field is its scale's value (c9-inputs: the figure's version)
    assert _departures("c9-inputs", "--scale", "paper", "--sim-version", "2017-04-22") == []
    assert _departures("c9-inputs", "--scale", "paper", "--sim-version", "2017-05-16") == [
        "--sim-version"]


def test_a_smaller_scale_run_may_write_beside_nothing_larger(tmp_path):
    _pair(tmp_path, "a.csv", scale="smoke")
    _pair(tmp_path, "a.csv", scale="paper")  # larger replaces smaller
    with pytest.raises(UsageError, match="paper"):
        _pair(tmp_path, "a.csv", scale="smoke")
    _pair(tmp_path, "a.csv", scale="smoke", overwrite=True)


# --- damaged but loadable checkpoints ------------------------------------------------------------

TRAIN = ["train", "--env", "wildfire", "--scale", "smoke", "--batch-episodes", "2"]


@pytest.fixture(scope="module")
def wildfire_run(tmp_path_factory):
    """A whole wildfire run of one epoch."""
    run = tmp_path_factory.mktemp("whole") / "run"
    assert _main([*TRAIN, "--epochs", "1", "--out", str(run)]) == 0
    return run


def _short_normaliser(s):
    s["normalizer"]["mean"] = s["normalizer"]["mean"][:-1]


def _nan_weight(s):
    s["policy"]["net.0.weight"][0, 0] = float("nan")


def _inf_variance(s):
    s["normalizer"]["var"][3] = float("inf")


def _other_inputs(s):
    """Consistent in itself, but for 27 observations where the wildfire gives 28."""
    s["policy"]["net.0.weight"] = s["policy"]["net.0.weight"][:, :-1].clone()
    s["normalizer"] = {"count": 5, "mean": torch.zeros(27, dtype=torch.float64),
                       "var": torch.ones(27, dtype=torch.float64)}
    s["baseline"] = {"coeffs": torch.zeros(58, dtype=torch.float64)}


def _wrong_layer(s):
    s["policy"]["net.0.bias"] = torch.zeros(16)  # its weight has a row per hidden unit


def _extra_action(s):
    """Consistent in itself, but for 7 actions where the wildfire has 6."""
    last = f"net.{2 * len(s['run_config']['train']['hidden'])}"
    s["policy"][f"{last}.weight"] = torch.cat([s["policy"][f"{last}.weight"],
                                               s["policy"][f"{last}.weight"][:1]])
    s["policy"][f"{last}.bias"] = torch.cat([s["policy"][f"{last}.bias"],
                                             s["policy"][f"{last}.bias"][:1]])


def _weights_as(dtype):
    """The damage: the policy's weights saved in ``dtype`` (trained: float32)."""
    def damage(s):
        s["policy"] = {k: v.to(dtype) for k, v in s["policy"].items()}
    return damage


DAMAGE = {
    "missing policy": lambda s: s.pop("policy"),
    "wrong layer shape": _wrong_layer,
    "other input size": _other_inputs,
    "short normaliser": _short_normaliser,
    "bad generator state": lambda s: s.update(sampler_rng={"bit_generator": "PCG64",
                                                           "state": "x"}),
    "bad torch generator state": lambda s: s.update(torch_rng=torch.zeros(3)),
    "NaN weight": _nan_weight,
    "Inf variance": _inf_variance,
    "negative epoch": lambda s: s.update(epoch=-3),
    "epoch not a number": lambda s: s.update(epoch="1"),
    "epoch beyond the run": lambda s: s.update(epoch=10**30),
    "an entry of its own": lambda s: s.update(notes="hello"),
    "one action more": _extra_action,
    **{f"{dtype} weights": _weights_as(dtype)
       for dtype in (torch.float16, torch.float64, torch.int64, torch.bool, torch.complex64)},
}


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_a_damaged_checkpoint_is_refused_in_one_line_everywhere(damage, wildfire_run, tmp_path,
                                                                  capsys, monkeypatch):
    """Built with the suite's own save_checkpoint, so it loads: train (resume), render,
    bench-wildfire and the API refuse it in one line, and the run folder is left as it was."""
    run = tmp_path / "run"
    shutil.copytree(wildfire_run, run)
    state = load_checkpoint(run / CHECKPOINT)
    DAMAGE[damage](state)
    save_checkpoint(run / CHECKPOINT, state)
    before = tree_snapshot(run)
    capsys.readouterr()
    assert _main([*TRAIN, "--epochs", "2", "--out", str(run)]) == 2
    _one_line(capsys, "--out")
    assert _main(["render", "--policy", "checkpoint", str(run / CHECKPOINT),
                  "--out", str(tmp_path / "a.gif")]) == 2
    _one_line(capsys, "--policy")
    assert _main(["bench-wildfire", "--scale", "smoke", "--checkpoint", str(run / CHECKPOINT),
                  "--results-dir", str(tmp_path / "res")]) == 2
    _one_line(capsys, "--checkpoint")
    if damage not in ("other input size", "one action more"):  # only an environment tells
        with pytest.raises(UsageError):
            policy_from_checkpoint(run / CHECKPOINT, np.random.default_rng(0))
    assert tree_snapshot(run) == before
    assert not (tmp_path / "a.gif").exists() and not (tmp_path / "res").exists()


@pytest.mark.parametrize("epochs", [1, 2])
def test_a_checkpoint_set_back_is_refused_before_the_run_changes(epochs, wildfire_run, tmp_path,
                                                                  capsys):
    """Its epoch set back to 0 in a finished run of one epoch: a resume would cut progress.csv
    and train again; refused in one line, the folder as it was. An acting command takes it (its
    epoch is within progress.csv), one beyond progress.csv is refused by all of them."""
    run = tmp_path / "run"
    shutil.copytree(wildfire_run, run)
    state = load_checkpoint(run / CHECKPOINT)
    save_checkpoint(run / CHECKPOINT, {**state, "epoch": 0})
    before = tree_snapshot(run)
    capsys.readouterr()
    assert _main([*TRAIN, "--epochs", str(epochs), "--out", str(run)]) == 2
    assert "holds the 1 epochs its last call finished with" in _one_line(capsys, "--out")
    assert tree_snapshot(run) == before
    kept = state_problem({k: state[k] for k in ("epoch", "policy", "normalizer", "run_config")})
    assert kept is None
    save_checkpoint(run / CHECKPOINT, {**state, "run_config": {
        **state["run_config"], "train": {**state["run_config"]["train"], "epochs": 5}},
        "epoch": 3})
    assert _main(["render", "--policy", "checkpoint", str(run / CHECKPOINT),
                  "--out", str(tmp_path / "a.gif")]) == 2
    assert "whose epoch (3) its run's progress.csv holds" in _one_line(capsys, "--policy")


def test_a_studys_damaged_run_is_refused_naming_runs_dir(wildfire_run, tmp_path):
    """A sweep's finished run whose checkpoint is damaged, or acts on another number of actions,
    is refused in one line naming --runs-dir (not train's --out), before a study tests it."""
    from repro.envs.wildfire import WildfireConfig
    from repro.studies.transfer.study import score_policy
    from repro.runs.run_folder import is_finished

    run = tmp_path / "run"
    shutil.copytree(wildfire_run, run)
    state = load_checkpoint(run / CHECKPOINT)
    _extra_action(state)
    save_checkpoint(run / CHECKPOINT, state)
    assert is_finished(run, 1)  # whole in itself: only the environment tells
    with pytest.raises(UsageError, match="--runs-dir: .*7 actions, the environment 6"):
        score_policy(WildfireConfig(), (run / CHECKPOINT).read_bytes(), [], 1, 0,
                     np.random.SeedSequence(0))
    _nan_weight(state)
    save_checkpoint(run / CHECKPOINT, state)
    with pytest.raises(UsageError, match="^--runs-dir: .*NaN"):
        is_finished(run, 1)


def test_a_whole_checkpoint_still_resumes(wildfire_run, tmp_path, monkeypatch):
    run = tmp_path / "run"
    shutil.copytree(wildfire_run, run)
    state = load_checkpoint(run / CHECKPOINT)
    assert state_problem(state, 28, 6) is None
    acting = {k: state[k] for k in ("epoch", "policy", "normalizer", "run_config")}
    assert state_problem(acting) is None  # a kept policy: what acting needs
    assert "baseline" in state_problem(acting, training=True)  # not enough to train on
    assert _main([*TRAIN, "--epochs", "2", "--out", str(run)]) == 0
    assert load_checkpoint(run / CHECKPOINT)["epoch"] == 2


# --- sizes and paths -----------------------------------------------------------------------------

REQUIRED = {"train": ["--env", "toy"], "render": ["--out", "x.gif"],
            "wildfire-eval": ["--policy", "nearest"], "bus-eval": ["--policy", "nohold"],
            "plot-runs": ["run"]}
"""The options a command needs besides the path under test."""


def _path_options(command: str) -> list[str]:
    import importlib

    from repro.cli import ALIASES, COMMANDS, PATH_OPTIONS, OneLineParser

    parser = OneLineParser(prog=command)
    module = importlib.import_module(COMMANDS[ALIASES.get(command, command)][0])
    module.add_arguments(parser)
    if hasattr(module, "extend_arguments"):
        module.extend_arguments(parser, REQUIRED.get(command, []))
    return [a.option_strings[0] for a in parser._actions if a.dest in PATH_OPTIONS]


def test_every_path_option_of_every_command_refuses_long_and_undecodable_paths(
        tmp_path, monkeypatch, capsys):
    """Over 4,096 bytes, or not UTF-8 (``train --out $'/tmp/run_\\xff\\xfe'``): one line naming
    the option, exit 2, nothing written."""
    from repro.cli import COMMANDS

    monkeypatch.chdir(tmp_path)
    long = "/".join(["d" * 200] * 21)  # 4,220 bytes, every name within the 255 a name may have
    undecodable = os.fsdecode(b"run_\xff\xfe")
    tried = 0
    for command in COMMANDS:
        for option in _path_options(command):
            for bad in (long, undecodable):
                argv = [command, *REQUIRED.get(command, []), option, bad]
                assert _main(argv) == 2, argv
                line = _one_line(capsys, option)
                assert ("4096 bytes" if bad == long else "UTF-8") in line, line
                tried += 1
    for bad in (long, undecodable):  # render's checkpoint comes after its --policy
        assert _main(["render", "--policy", "checkpoint", bad, "--out", "x.gif"]) == 2
        _one_line(capsys, "--policy")
    assert tried >= 40 and list(tmp_path.iterdir()) == []


SIXTEEN_GIB = 16 << 30


@pytest.mark.parametrize("argv, param", [
    (["train", "--env", "wildfire", "--scale", "smoke", "--batch-episodes", "100000000"],
     "--batch-episodes"),
    (["train", "--env", "bus", "--scale", "smoke", "--batch-episodes", "100000000"],
     "--batch-episodes"),
    (["train", "--env", "wildfire", "--scale", "smoke", "--hidden", "100000", "100000"],
     "--hidden"),
    (["wildfire-eval", "--policy", "nearest", "--episodes", "100000000"], "--episodes"),
    (["bench-bus", "--scale", "smoke", "--fast-episodes", "100000000"], "--fast-episodes"),
    (["bench-wildfire", "--scale", "smoke", "--reference-episodes", "100000000"],
     "--reference-episodes"),
    (["fig-transfer", "--scale", "smoke", "--batch-decisions", "100000000"],
     "--batch-decisions"),
    (["fig-transfer", "--scale", "smoke", "--learner", "suite", "--batch-episodes", "100000000"],
     "--batch-episodes"),
    (["scaling", "--scale", "smoke", "--n-agents", "2", "3", "100000000"], "--n-agents"),
    (["scaling", "--scale", "smoke", "--duration", "inf"], "--duration"),
    (["scaling", "--scale", "smoke", "--duration", "1e12"], "--duration"),
    (["fig-bus-arrivals", "--scale", "smoke", "--policies", "nohold", "--thresholds", "nan",
      "nan", "nan"], "--thresholds"),
    (["render", "--policy", "nearest", "--out", "/proc/a.gif"], "--out"),
    *[([command, *rest, flag, str(10**40)], flag) for command, rest, flag in [
        ("fig-transfer", ["--scale", "smoke"], "--seeds"),
        ("fig-transfer", ["--scale", "smoke"], "--n-jobs"),
        ("fig-transfer", ["--scale", "smoke"], "--epochs"),
        ("fig-transfer", ["--scale", "smoke"], "--test-episodes"),
        ("fig-transfer", ["--scale", "smoke"], "--seed"),
        ("bench-bus", ["--scale", "smoke"], "--repeats"),
        ("render", ["--policy", "nearest", "--out", "a.gif"], "--fps"),
        ("render", ["--policy", "nearest", "--out", "a.gif"], "--frames"),
        ("race", ["--scale", "smoke"], "--bisection-steps"),
        ("bus-thresholds", ["--scale", "smoke"], "--popsize"),
        ("wildfire-eval", ["--policy", "nearest"], "--max-decisions"),
        ("train", ["--env", "wildfire", "--scale", "smoke"], "--epochs"),
    ]],
    (["beyond-races", "--scale", "smoke", "--log10-dt-step", "inf"], "--log10-dt-step"),
    (["train", "--env", "bus", "--scale", "smoke", "--epoch", "2"], "--epoch"),
    (["bus-eval", "--policy", "mlp", "--learner", "/../../TRAV"], "--learner"),
    (["fig-bus-load", "--scale", "smoke", "--learner", "/../../TRAV"], "--learner"),
    (["fig-bus-arrivals", "--scale", "smoke", "--learner", "/../../TRAV"], "--learner"),
    (["fig-bus-lambda", "--scale", "smoke", "--runs-dir", ""], "--runs-dir"),
])
def test_sizes_the_machine_cannot_hold_are_refused_up_front(argv, param, tmp_path, monkeypatch,
                                                             capsys):
    """Memory estimates are checked against 16 GiB here, whatever this machine has, so that the
    probe's sizes are refused alike everywhere; sizes far beyond any study's (10^40), options
    abbreviated, a learner that is none and an empty folder name are refused too; nothing runs,
    nothing is written."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(memory, "available_memory", lambda: SIXTEEN_GIB)
    t0 = time.perf_counter()
    assert _main(argv) == 2
    assert time.perf_counter() - t0 < 20
    line = _one_line(capsys, param)
    if "memory" in line:
        assert "16.0 GiB available" in line
    assert not [p for p in tmp_path.rglob("*") if p.is_file()]



def test_a_config_file_gives_a_folder_as_text_only(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "c.json").write_text('{"results_dir": 5}')
    assert _main([*RACE, "--config", "c.json"]) == 2
    assert "c.json: results_dir: must be a string" in _one_line(capsys, "results_dir")
    assert [p.name for p in tmp_path.iterdir()] == ["c.json"]

def test_the_sizes_of_the_paper_scale_fit():
    """The estimates are lower bounds: nothing the paper's scale asks for comes near a limit."""
    from repro.core.config import for_scale
    from repro.envs.bus import make_env as bus_env
    from repro.envs.wildfire import WildfireConfig, make_env
    from repro.studies.races.scaling import check_work, ScalingConfig
    from repro.learn.config import train_config
    from repro.learn.sizes import training_bytes

    for env in (make_env(WildfireConfig()), bus_env()):
        assert sum(training_bytes(train_config("paper", env.name), env)) < 1 << 30
        assert rollout_bytes(env, 10_000, keep_obs=False, batch=1000) < 1 << 30
    check_work(for_scale(ScalingConfig, "paper"))


def test_a_full_disk_names_the_file(tmp_path, monkeypatch, capsys):
    """A write to an open file that fails (a full disk) carries no file name of its own."""
    import errno
    from pathlib import Path

    def full(self, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(Path, "write_bytes", full)
    assert _main([*RACE, "--results-dir", str(tmp_path / "r")]) == 1
    line = _one_line(capsys, "No space left on device")
    assert line.endswith(str(tmp_path / "r" / "table_race.csv")), line
