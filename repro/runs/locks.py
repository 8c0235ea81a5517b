"""One writer per folder: an exclusive ``flock`` on a lock file in it that names its holder.

A second writer is refused at once (a UsageError naming the holder) rather than made to wait. The
kernel releases the lock when its process dies, so a lock left by a killed writer is taken over by
the next one. The lock file is removed on release; a writer that finds the file it locked unlinked
(by a releasing writer) locks the new one instead.
"""

from __future__ import annotations

import errno
import fcntl
import os
import socket
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from repro.core.errors import UsageError


@contextmanager
def folder_lock(folder: str | Path, name: str, param: str, what: str,
                wait: float = 0.0) -> Iterator[None]:
    """Hold ``folder``/``name`` while the block runs (the folder is created, and removed again
    with the ancestors it needed if nothing was written there: a refusal leaves no empty
    folders). If another process holds it after ``wait`` seconds: a UsageError naming ``param``,
    "must be ``what`` no other process is writing to (<holder> holds <name>)"."""
    folder = Path(folder)
    created = _missing(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with _held(folder, name, param, what, wait):
            yield
    finally:
        _remove_empty(created)


def _missing(folder: Path) -> list[Path]:
    """``folder`` and its ancestors that do not exist yet, deepest first."""
    out = []
    while not folder.exists() and folder.parent != folder:
        out.append(folder)
        folder = folder.parent
    return out


def _remove_empty(folders: list[Path]) -> None:
    for folder in folders:
        try:
            folder.rmdir()
        except OSError:  # something was written there (or it went already)
            return


@contextmanager
def _held(folder: Path, name: str, param: str, what: str, wait: float) -> Iterator[None]:
    """:func:`folder_lock` in an existing ``folder``."""
    path = folder / name
    give_up = time.monotonic() + wait
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            holder = os.read(fd, 200).decode(errors="replace").strip() or "another process"
            os.close(fd)
            if err.errno not in (errno.EAGAIN, errno.EACCES):
                raise
            if time.monotonic() < give_up:
                time.sleep(0.01)
                continue
            raise UsageError(param, f"{what} no other process is writing to ({holder} holds "
                             f"{name})", str(folder)) from None
        if os.path.exists(path) and os.stat(path).st_ino == os.fstat(fd).st_ino:
            break
        os.close(fd)  # the file was removed by a releasing writer: lock the new one
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"pid {os.getpid()} on {socket.gethostname()}".encode())
        yield
    finally:
        os.unlink(path)
        os.close(fd)


def is_locked(folder: str | Path, name: str) -> str | None:
    """The holder of ``folder``/``name`` if another process holds it now, else None; changes
    nothing (a check before work: the lock itself is taken later)."""
    path = Path(folder) / name
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError:
        return os.read(fd, 200).decode(errors="replace").strip() or "another process"
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)
