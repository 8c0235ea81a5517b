"""A training run's folder and the promises it keeps.

A run folder holds ``config.json`` (the settings that determine the run), ``progress.csv`` (one row
per finished epoch), ``checkpoint.pt`` (everything needed to go on) and, while a process trains in
it, ``run.lock``.

- **Safe to load.** A checkpoint holds only tensors, numbers and strings (the run's config and the
  sampler's generator state as JSON) and is read with ``torch.load(weights_only=True)``, which
  refuses anything else: a crafted file cannot run code, it is refused as unreadable.
- **Same run, same bytes.** torch names a checkpoint's zip records after the file it writes, and
  atomic writes go to a randomly named temporary file; serialising into memory first gives
  identical runs identical checkpoints.
- **One writer.** ``run.lock`` is held with ``flock`` and names its holder (pid, host); a second
  writer is refused, naming the holder. The kernel releases the lock when its process dies, so a
  lock left by a killed run is taken over by the next one.
- **Exact resume at every kill point.** Epoch e's row is appended to progress.csv before epoch e is
  checkpointed, and a (re)started run first cuts progress.csv back to its checkpoint's epochs (all
  of it when there is no checkpoint yet). So whichever write a kill interrupts, running the same
  command again ends with the files of an uninterrupted run. Temporary files of interrupted atomic
  writes are removed then too.
- **Damage is one line.** An unreadable ``config.json`` or checkpoint, a checkpoint of another run,
  or a progress table missing checkpointed rows is refused (exit status 2) naming the file and what
  to do, before anything in the folder is changed.
"""

from __future__ import annotations

import io
import json
from contextlib import AbstractContextManager
from pathlib import Path
from typing import Any

import pandas as pd
import torch

from repro.core.errors import UsageError, require
from repro.core.io import append_csv, write_bytes, write_csv, write_json, write_text
from repro.core.locks import folder_lock, is_locked

CONFIG = "config.json"
PROGRESS = "progress.csv"
PROVENANCE = "progress.provenance.json"
CHECKPOINT = "checkpoint.pt"
LOCK = "run.lock"
CHECKPOINT_FORMAT = 2
"""Version of the checkpoint's layout; 1 (before it was safe to load) held numpy objects."""
_JSON_FIELDS = ("run_config", "sampler_rng")
"""Checkpoint entries stored as JSON strings (nested dicts with 128-bit integers in the case of the
generator state, which ``weights_only`` loading would not take as they are)."""


# --- checkpoints ---------------------------------------------------------------------------------

def save_checkpoint(path: str | Path, state: dict[str, Any]) -> None:
    """Write ``state`` (tensors, numbers, strings, and the JSON-able entries of ``_JSON_FIELDS``)
    atomically, the same bytes for the same state."""
    encoded = {**state, "format": CHECKPOINT_FORMAT,
               **{k: json.dumps(state[k], sort_keys=True) for k in _JSON_FIELDS if k in state}}
    buffer = io.BytesIO()
    torch.save(encoded, buffer)
    write_bytes(path, buffer.getvalue())


def load_checkpoint(path: str | Path, param: str = "--out",
                    allowed: str | None = None) -> dict[str, Any]:
    """The state saved by :func:`save_checkpoint`; anything else (a crafted pickle, a truncated,
    empty or random file, a folder, an older format) is a :class:`UsageError` naming ``param``."""
    allowed = allowed or f"a readable {CHECKPOINT} of this suite (delete it to start the run again)"
    try:
        state = torch.load(path, weights_only=True)
        require(isinstance(state, dict) and state.get("format") == CHECKPOINT_FORMAT, param,
                allowed, str(path))
        return {**state, **{k: json.loads(state[k]) for k in _JSON_FIELDS if k in state}}
    except UsageError:
        raise
    except Exception:  # whatever torch or the unpickler raises for a file that is not ours
        raise UsageError(param, allowed, str(path)) from None


# --- the run's identity --------------------------------------------------------------------------

def read_config(folder: Path, param: str = "--out") -> dict[str, Any] | None:
    """The run's ``config.json`` (None if it has none); an unreadable one is a UsageError."""
    path = folder / CONFIG
    if not path.exists():
        return None
    try:
        saved = json.loads(path.read_text())
        if not isinstance(saved, dict):
            raise ValueError(saved)
        return saved
    except (OSError, ValueError):
        raise UsageError(param, f"a run folder with a readable {CONFIG} (repair or delete it)",
                         str(path)) from None


def run_difference(saved: dict[str, Any], mine: dict[str, Any],
                   defaults: dict[str, Any]) -> str | None:
    """The first setting (other than ``train.epochs``) in which the run config ``saved`` differs
    from ``mine``, as "part.key: saved vs mine"; None if they are the same run. Settings that
    ``saved`` lacks were added to the code after the run started, so they held their defaults."""
    for part in sorted(set(saved) | set(mine)):
        a, b = saved.get(part), _as_json(mine.get(part))
        if isinstance(a, dict) and isinstance(b, dict):
            a = {**_as_json(defaults.get(part) or {}), **a}
            for key in sorted(set(a) | set(b)):
                if (part, key) != ("train", "epochs") and a.get(key) != b.get(key):
                    return f"{part}.{key}: {a.get(key)!r} there, {b.get(key)!r} here"
        elif a != b:
            return f"{part}: {a!r} there, {b!r} here"
    return None


def _as_json(value: Any) -> Any:
    return json.loads(json.dumps(value, default=str))


def is_new(folder: Path) -> bool:
    """Whether ``folder`` is missing or holds nothing but a lock or leftovers of interrupted writes
    (a folder of other files is not a run)."""
    ours = {LOCK, *(p.name for p in _leftovers(folder))}
    return not folder.is_dir() or all(p.name in ours for p in folder.iterdir())


def _leftovers(folder: Path) -> list[Path]:
    """Temporary files of atomic writes that a kill interrupted."""
    return list(folder.glob(".*.tmp*"))


def check_same_run(folder: Path, mine: dict[str, Any], defaults: dict[str, Any],
                   param: str = "--out") -> None:
    """Refuse (UsageError naming ``param``) a folder that is neither new nor a run with the
    settings ``mine``; reads only."""
    saved = read_config(folder, param)
    if saved is None:
        require(is_new(folder), param, "new, empty or a run folder", str(folder))
        return
    diff = run_difference(saved, mine, defaults)
    require(diff is None, param, f"a run folder made with these settings ({CONFIG}: {diff})",
            str(folder))


# --- resuming ------------------------------------------------------------------------------------

def resume_state(folder: Path, mine: dict[str, Any], defaults: dict[str, Any],
                 param: str = "--out") -> dict[str, Any] | None:
    """Check everything a (re)start needs, changing nothing: the folder holds this run (or none),
    its checkpoint (if any) is readable and of this run, and progress.csv holds its epochs.
    Returns the checkpoint's state, or None."""
    check_same_run(folder, mine, defaults, param)
    path = folder / CHECKPOINT
    if not path.exists():
        return None
    state = load_checkpoint(path, param)
    diff = run_difference(state.get("run_config") or {}, mine, defaults)
    require(diff is None, param, f"a run folder whose {CHECKPOINT} belongs to its run ({diff}; "
            f"delete {CHECKPOINT} to start again)", str(folder))
    rows = _rows(folder / PROGRESS)
    epochs = int(state["epoch"])
    require(rows >= epochs, param, f"a run folder whose {PROGRESS} holds the {epochs} epochs of "
            f"its {CHECKPOINT} (it holds {rows}; delete {CHECKPOINT} to start again)", str(folder))
    return state


def _rows(path: Path) -> int:
    return max(len(path.read_text().splitlines()) - 1, 0) if path.exists() else 0


def restore(folder: Path, epochs: int, config: dict[str, Any],
            columns: list[str]) -> list[dict[str, Any]]:
    """Make ``folder`` the state an uninterrupted run has after ``epochs`` epochs: remove leftover
    temporary files, write ``config`` to config.json, cut progress.csv back to ``epochs`` rows
    (a row appended after the last checkpoint, whole or cut short, goes) in ``columns`` (a column
    that a run recorded before it existed is left empty in its rows). Returns those rows."""
    for leftover in _leftovers(folder):
        leftover.unlink()
    write_json(folder / CONFIG, config)
    path = folder / PROGRESS
    if epochs == 0:
        path.unlink(missing_ok=True)
        return []
    lines = path.read_text().splitlines(keepends=True)
    if len(lines) != epochs + 1:
        write_text(path, "".join(lines[:epochs + 1]))
    table = pd.read_csv(path)
    if list(table.columns) != columns:
        table = table.reindex(columns=columns)
        write_csv(path, table)
    return table.to_dict("records")


def append_row(folder: Path, row: dict[str, Any], columns: list[str]) -> None:
    """Append one epoch's row to progress.csv (appended, because rewriting the table every epoch
    grows with the run: 0.18 s per epoch by epoch 1,550 of a paper-scale C6 run)."""
    append_csv(folder / PROGRESS, pd.DataFrame([row], columns=columns))


def epochs_done(folder: str | Path) -> int:
    """Epochs the checkpoint of the run in ``folder`` holds (0 if it has none)."""
    path = Path(folder) / CHECKPOINT
    return int(load_checkpoint(path)["epoch"]) if path.exists() else 0


def is_finished(folder: str | Path, epochs: int) -> bool:
    """Whether the run in ``folder`` has ``epochs`` epochs and its last ``train`` call ended
    (its provenance sidecar is written last, and no write was left half done)."""
    folder = Path(folder)
    return ((folder / PROVENANCE).exists() and not _leftovers(folder)
            and epochs_done(folder) >= epochs)


# --- one writer ----------------------------------------------------------------------------------

def writer_lock(folder: Path, param: str = "--out") -> AbstractContextManager[None]:
    """Hold ``folder``'s run.lock while the block runs; a UsageError naming the holder if another
    process holds it (:func:`repro.core.locks.folder_lock`)."""
    return folder_lock(folder, LOCK, param, "a run folder")


def locked_by(folder: Path) -> str | None:
    """The holder of ``folder``'s run.lock if another process holds it now, else None."""
    return is_locked(folder, LOCK)
