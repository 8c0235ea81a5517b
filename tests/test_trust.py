"""Nothing hangs, nothing crashes on a refusal, nothing half-trusted is used: the scheduler
address, refusals from worker processes, results folders and their pairs, damaged checkpoints,
sizes and paths."""

from __future__ import annotations

import socket
import threading
import time

import pytest

from repro.cli import main
from repro.core.errors import UsageError
from repro.experiments import sweep


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
