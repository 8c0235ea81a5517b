"""Nothing hangs, nothing crashes on a refusal, nothing half-trusted is used: the scheduler
address, refusals from worker processes, results folders and their pairs, damaged checkpoints,
sizes and paths."""

from __future__ import annotations

import pickle
import socket
import threading
import time

import pytest

from repro.cli import main
from repro.core.errors import UsageError, require
from repro.core.locks import folder_lock
from repro.experiments import sweep
from repro.learn.run_folder import writer_lock


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
    monkeypatch.setattr(sweep, "SCHEDULER_DEADLINE", 1.0)
    monkeypatch.setenv("REPRO_QUIET", "1")
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
    assert not (tmp_path / "res").exists()
    assert not any(p.is_file() for p in (tmp_path / "runs").rglob("*"))


# --- refusals across processes -------------------------------------------------------------------

def test_a_refusal_pickles_as_itself():
    err = pickle.loads(pickle.dumps(UsageError("--runs-dir", "x", "/x")))
    assert type(err) is UsageError and str(err) == "--runs-dir: must be x, got '/x'"
    assert (err.param, err.allowed, err.got) == ("--runs-dir", "x", "/x")


def test_a_refusal_in_a_worker_process_reaches_the_caller_intact():
    with pytest.raises(UsageError) as caught:
        sweep.map_tasks(require, [(True, "--a", "b"), (False, "--runs-dir", "free", "/r")],
                        n_jobs=2)
    assert str(caught.value) == "--runs-dir: must be free, got '/r'"


def _transfer(tmp_path, *more: str) -> list[str]:
    return ["fig-transfer", "--scale", "smoke", "--simulator", "ED", "--test-episodes", "5",
            "--runs-dir", str(tmp_path / "runs"), "--results-dir", str(tmp_path / "res"),
            "--figures-dir", str(tmp_path / "fig"), *more]


def test_a_sweep_meeting_a_run_folder_in_use_is_refused_naming_runs_dir(tmp_path, capsys,
                                                                         monkeypatch):
    """Two jobs pending, one of them being written by another process: one line naming
    --runs-dir, exit 2, and nothing trained."""
    monkeypatch.setenv("REPRO_QUIET", "1")
    root = tmp_path / "runs" / "transfer" / "smoke"
    with writer_lock(root / "ed-th3-seed1"):
        assert _main(_transfer(tmp_path, "--seeds", "2", "--n-jobs", "2")) == 2
    line = _one_line(capsys, "--runs-dir")
    assert "ed-th3-seed1" in line and "pid" in line
    assert not (root / "ed-th3-seed0").exists() and not (tmp_path / "res").exists()


def test_a_second_sweep_over_the_same_runs_is_refused_naming_runs_dir(tmp_path, capsys,
                                                                      monkeypatch):
    monkeypatch.setenv("REPRO_QUIET", "1")
    root = tmp_path / "runs" / "transfer" / "smoke"
    with folder_lock(root, sweep.SWEEP_LOCK, "--runs-dir", "a folder of runs"):
        assert _main(_transfer(tmp_path, "--n-jobs", "2")) == 2
    assert "sweep.lock" in _one_line(capsys, "--runs-dir")
    assert [p.name for p in root.iterdir()] == []
