"""Atomic, deterministic files: every file is written to a temporary file in its destination
folder and renamed into place, so an interrupted run never leaves a half-written file; CSVs are
written with a fixed float format, so the same computation gives byte-identical files. Paths named
by the user are checked here before any work (their names, and that their folder is writable).
"""

from __future__ import annotations

import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterator

from repro.core.errors import UsageError, require

if TYPE_CHECKING:  # pandas is imported where a table is written or read: the CLI starts lighter
    import pandas as pd

NAME_MAX = 255
"""The longest file or folder name (bytes) Linux and macOS file systems take."""
PATH_MAX = 4096
"""The longest path (bytes, with its terminating zero byte) Linux takes; macOS takes 1024."""

FLOAT_FORMAT = "%.10g"
"""Ten significant digits: well above every quantity's precision, and stable across platforms."""


def check_writable_dir(path: str | Path, param: str) -> Path:
    """Fail early (before any work or write) if ``path`` cannot become a writable folder.

    Permission bits say nothing for root or for special file systems, so the nearest existing
    ancestor is probed by creating and removing a temporary folder in it; nothing is left behind.
    """
    require(str(path).strip() != "", param, "a writable folder (not an empty path)", str(path))
    p = check_names(path, param)
    probe = p
    while not probe.exists() and probe.parent != probe:
        probe = probe.parent
    try:
        if not probe.is_dir():
            raise NotADirectoryError(probe)
        tempfile.TemporaryDirectory(dir=probe, prefix=".probe-").cleanup()
    except OSError:
        raise UsageError(param, "a writable folder", str(path)) from None
    return p


def check_names(path: str | Path, param: str) -> Path:
    """``path``, unless it is not UTF-8 (a name of other bytes cannot be recorded in a sidecar or
    printed), longer than the system takes, or one of its names longer than a file system takes
    (UsageError)."""
    text = str(path)
    try:
        text.encode()
    except UnicodeEncodeError:  # argv's undecodable bytes arrive as lone surrogates
        raise UsageError(param, "a path in UTF-8", _raw(text)) from None
    size = len(os.path.abspath(text).encode()) if text else 0
    require(size < PATH_MAX, param, f"a path of fewer than {PATH_MAX} bytes",
            f"{text[:20]}... ({size} bytes)")
    long = next((part for part in Path(path).parts if len(part.encode()) > NAME_MAX), None)
    require(long is None, param, f"a path whose names have at most {NAME_MAX} bytes",
            f"{long[:20]}... ({len(long.encode())} bytes)" if long else None)
    return Path(path)


def _raw(text: str) -> bytes | str:
    """The bytes a path of argv stands for (its undecodable bytes arrive as lone surrogates)."""
    try:
        return os.fsencode(text)
    except UnicodeEncodeError:
        return text.encode(errors="backslashreplace").decode()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


FILE_MODE = 0o666 & ~_umask()
"""The mode an ordinary ``open`` would give a new file; mkstemp's files are private (0600)."""


@contextmanager
def atomic_path(dest: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``dest``; on success it is renamed onto ``dest``, with the
    permissions an ordinary write would give it."""
    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".tmp" + dest.suffix,
                               dir=dest.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, FILE_MODE)
        os.replace(tmp, dest)
    except OSError as err:
        if err.filename is None:  # a write to an open file (a full disk) names no file
            err.filename = str(dest)
        raise
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_text(dest: str | Path, text: str) -> None:
    with atomic_path(dest) as tmp:
        tmp.write_text(text)


def write_bytes(dest: str | Path, data: bytes) -> None:
    with atomic_path(dest) as tmp:
        tmp.write_bytes(data)


def write_json(dest: str | Path, obj: Any) -> None:
    write_text(dest, json.dumps(obj, indent=2, sort_keys=True, default=str) + "\n")


def write_csv(dest: str | Path, frame: pd.DataFrame) -> None:
    with atomic_path(dest) as tmp:
        frame.to_csv(tmp, index=False, float_format=FLOAT_FORMAT, lineterminator="\n")


def append_csv(dest: str | Path, frame: pd.DataFrame) -> None:
    """Append ``frame``'s rows to the CSV ``dest`` (created with a header), formatted as
    :func:`write_csv` formats them. Not atomic: a reader that must see whole rows only keeps the
    rows it knows to be complete (a resumed training run keeps its checkpoint's epochs)."""
    dest = Path(dest)
    new = not dest.exists()
    try:
        with dest.open("a", newline="") as f:
            frame.to_csv(f, header=new, index=False, float_format=FLOAT_FORMAT,
                         lineterminator="\n")
    except OSError as err:
        if err.filename is None:
            err.filename = str(dest)
        raise
