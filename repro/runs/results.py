"""Atomic, deterministic result files and their provenance sidecars, and the folders they live in.

Every result is written to a temporary file in the destination folder and renamed into place, so an
interrupted run never leaves a half-written file. CSVs are written with a fixed float format, so the
same computation gives byte-identical files.

A result is a pair, a CSV and its sidecar, and the pair is trusted only whole:

- **Pairs that cannot tear.** The sidecar records the SHA-256 of its CSV's bytes; a reader
  (:func:`read_result`) takes a CSV only with the sidecar that describes it, and anything else (a
  sidecar missing, or written for other bytes) reads as a missing result, "not yet run".
  Sidecars written before the hash was recorded (the committed results of 2026-11-25 and before)
  carry none and are taken as they are.
- **One writer per results folder.** A driver holds its results folder's ``results.lock`` from
  its up-front checks to its end (:func:`open_results`); a second writer is refused in one line
  naming the holder. A pair written outside a driver takes the lock for that pair alone.
- **Provenance guards results, not folder names.** A run never replaces a result whose sidecar
  records a larger scale (smoke < quick < paper) unless told to (``--overwrite``); a driver checks
  its results folder for such results before any work.
- **Provenance is written once.** A sidecar is never edited after its run; a later correction
  of one of its fields is a separate, dated note beside it, ``<stem>.correction-<date>.json``
  (:func:`write_correction`), and :func:`shown_provenance` shows the sidecar with its notes. A
  note marked ``in_place`` records an edit made in the sidecar itself before this rule: the sidecar
  holds the note's ``value``, and the note keeps what the run wrote (``recorded``). A run that
  makes a result's CSV again byte for byte, at the scale its sidecar records, keeps the first
  sidecar and leaves a note of its own beside it, ``<stem>.recreated-<time>.json`` with its
  provenance (:func:`write_result`): the first run stays the result's author, and each
  re-creation is on record.
- **The paper scale is what was run, not what was asked.** A run started with ``--scale paper``
  and settings of its own (``race --scale paper --n-sets 10``) records the scale ``custom``
  (:func:`repro.runs.provenance.run_scale`), below every scale: it neither replaces paper-scale
  results nor counts as one for the claims.

Figures are guarded the same way. A figure is ``<stem>.png`` and ``<stem>.pdf`` with a sidecar,
``<stem>.provenance.json``, that records both files' SHA-256, the result CSVs it was drawn from
(each with its hash and scale) and the scale (:func:`save_figure`). A driver checks its figures
folder for figures of a larger scale before any work (:func:`open_figures`), and a figure is not
replaced by one of a smaller scale unless told to; figures without a sidecar are replaced. A
figure drawn again byte for byte from the same sources keeps its first sidecar, with a
re-creation note beside it, as a result does. A figure's sidecar has the name of its stem's
result's, so a figures folder is never the results folder.
"""

from __future__ import annotations

import errno
import hashlib
import io
import json
import time
from contextlib import ExitStack, nullcontext
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

from repro.core.config import SCALES
from repro.core.errors import UsageError, require
from repro.runs.files import FLOAT_FORMAT, check_writable_dir, write_bytes, write_json
from repro.runs.locks import folder_lock
from repro.runs.provenance import (forget_departures, forget_trained_under, run_record,
                                   run_scale, scale_text)

if TYPE_CHECKING:
    import pandas as pd

def sidecar_path(result: str | Path) -> Path:
    """``results/x.csv`` -> ``results/x.provenance.json``."""
    result = Path(result)
    return result.with_name(result.stem + ".provenance.json")


CSV_HASH = "csv_sha256"
"""The sidecar's record of its CSV: the SHA-256 of the CSV's bytes (hex)."""
RESULTS_LOCK = "results.lock"
"""Held in a results folder by the process writing into it."""
FIGURES_LOCK = "figures.lock"
"""Held in a figures folder by the process drawing into it."""
PAIR_WAIT = 10.0
"""Seconds a pair written outside a driver waits for its folder's lock (another pair's write
takes milliseconds; a driver holding the folder, its whole run)."""

_session = ExitStack()
"""The results folders this process holds until :func:`release_results`."""
_held: dict[Path, bool] = {}
"""Those folders (resolved), each with whether its results may replace larger-scale ones."""
_figures_held: dict[Path, bool] = {}
"""The figures folders this process has opened (resolved, :func:`open_figures`), each with whether
its figures may replace larger-scale ones."""


FIGURE_FORMATS = (".png", ".pdf")
"""The files of a figure, each ``<stem><format>``."""
FIGURE_OPTIONS = {".png": {"dpi": 150}, ".pdf": {"metadata": {"CreationDate": None}}}
"""How each format is drawn (matplotlib's savefig)."""


def figure_sidecar(stem: str | Path) -> Path:
    """``figures/x`` -> ``figures/x.provenance.json``: the sidecar of a figure's files."""
    return Path(str(stem) + ".provenance.json")


def source_records(sources: Sequence[str | Path]) -> list[dict[str, Any]]:
    """What a figure's sidecar records of each result CSV it was drawn from: its path, the hash
    its sidecar records (or, for a sidecar without one, the hash of its bytes), and its sidecar's
    scale, command and commit, with the sidecar's correction notes (:func:`write_correction`)."""
    out = []
    for source in sources:
        source = Path(source)
        try:
            prov = json.loads(sidecar_path(source).read_text())
        except (OSError, ValueError):
            prov = {}
        prov = prov if isinstance(prov, dict) else {}
        digest = prov.get(CSV_HASH) or hashlib.sha256(source.read_bytes()).hexdigest()
        out.append({"csv": str(source), CSV_HASH: digest, "scale": prov.get("scale"),
                    "command": prov.get("command"), "git_commit": prov.get("git_commit"),
                    **_corrections(source)})
    return out


def figure_scale(records: list[dict[str, Any]]) -> Any:
    """A figure's scale: that of its first source, the result it shows (each source's own scale
    is recorded beside it)."""
    return records[0]["scale"] if records else None


def save_figure(fig: Any, stem: str | Path, sources: Sequence[str | Path], *,
                overwrite: bool = False, formats: Sequence[str] = FIGURE_FORMATS,
                param: str = "--figures-dir") -> list[Path]:
    """Lay ``fig`` out, draw it as ``stem.png`` and ``stem.pdf`` (or ``formats``; the PDF without
    a timestamp, so it is stable), close it, and write the files with their sidecar
    (:func:`write_figure`)."""
    import matplotlib.pyplot as plt  # loaded already by the caller that drew ``fig``

    fig.tight_layout()
    files = {}
    for ext in formats:
        buf = io.BytesIO()
        fig.savefig(buf, format=ext[1:], bbox_inches="tight", **FIGURE_OPTIONS[ext])
        files[Path(str(stem) + ext)] = buf.getvalue()
    plt.close(fig)
    return write_figure(stem, files, sources, overwrite=overwrite, param=param)


def write_figure(stem: str | Path, files: dict[Path, bytes], sources: Sequence[str | Path], *,
                 overwrite: bool = False, extra: dict[str, Any] | None = None,
                 param: str = "--figures-dir") -> list[Path]:
    """Write a figure's ``files`` (path -> bytes; ``stem`` and a suffix each) atomically, then
    their sidecar ``stem.provenance.json``: the files' hashes, the CSVs they were drawn from
    (``sources``, :func:`source_records`; the first is the result the figure shows), its scale
    (its first source's), the command, the process's :func:`run_record`, and ``extra``.

    Refused (UsageError naming ``param``, the option that named the folder) if ``stem`` is a
    figure whose sidecar records a larger scale, unless ``overwrite`` or its folder was opened
    with it (:func:`open_figures`), and if
    another process holds the folder (a folder this process did not open is locked for the write,
    waiting up to :data:`PAIR_WAIT`). As for a result, the old sidecar goes first, so that a
    sidecar never describes files it was not written with, and files that are already there byte
    for byte, drawn from the same sources at the same scale, keep their first sidecar with a
    re-creation note beside it (:func:`_figure_holds`)."""
    records = source_records(sources)
    mine = figure_scale(records)
    folder = Path(stem).parent
    held = folder.resolve() in _figures_held
    with (nullcontext() if held else folder_lock(folder, FIGURES_LOCK, param, "a figures folder",
                                                  wait=PAIR_WAIT)):
        theirs = _recorded_figure_scale(figure_sidecar(stem))
        if scale_rank(theirs) > scale_rank(mine) and not (
                overwrite or _figures_held.get(folder.resolve())):
            _refuse_larger([(next(iter(files)).name, theirs)], mine, param, folder, "figures")
        prov = {"command": records[0]["command"] if records else None, "scale": mine,
                "figures": {dest.name: hashlib.sha256(data).hexdigest()
                            for dest, data in files.items()},
                "sources": records, **run_record(), **(extra or {})}
        side = figure_sidecar(stem)
        if _figure_holds(side, files, prov):
            _note_recreation(side, prov)
            return list(files)
        side.unlink(missing_ok=True)
        for note in recreation_paths(side):  # notes of the sidecar just removed
            note.unlink()
        for dest, data in files.items():
            write_bytes(dest, data)
        write_json(side, prov)
    return list(files)


def _figure_holds(side: Path, files: dict[Path, bytes], prov: dict[str, Any]) -> bool:
    """Whether the figure whose sidecar is ``side`` is already ``files``, drawn from the same
    sources at the same scale as ``prov`` records: a figure drawn again byte for byte keeps its
    first sidecar, as a result does (:func:`write_result`)."""
    try:
        theirs = json.loads(side.read_text())
        same_files = all(dest.read_bytes() == data for dest, data in files.items())
    except (OSError, ValueError):
        return False
    return same_files and isinstance(theirs, dict) and all(
        theirs.get(key) == prov[key] for key in ("figures", "sources", "scale"))


def scale_rank(scale: Any) -> int:
    """The order of ``scale`` among :data:`~repro.core.config.SCALES` (-1 for none or unknown)."""
    return SCALES.index(scale) if scale in SCALES else -1


def _recorded_scale(result: Path) -> Any:
    """The scale the sidecar of ``result`` records (None if it has none or cannot be read)."""
    try:
        return json.loads(sidecar_path(result).read_text()).get("scale")
    except (OSError, ValueError, AttributeError):
        return None


def larger_results(folder: Path, scale: str | None) -> list[tuple[str, str]]:
    """(CSV name, its scale) of the results directly in ``folder`` whose sidecars record a scale
    larger than ``scale``."""
    out = []
    for side in sorted(Path(folder).glob("*.provenance.json")):
        csv = side.with_name(side.name.removesuffix(".provenance.json") + ".csv")
        theirs = _recorded_scale(csv)
        if scale_rank(theirs) > scale_rank(scale):
            out.append((csv.name, theirs))
    return out


def _recorded_figure_scale(side: Path) -> Any:
    """The scale the sidecar ``side`` records (None if there is none or it cannot be read): in a
    figures folder, a result's sidecar counts as a figure's, since a figure would replace it."""
    try:
        prov = json.loads(side.read_text())
    except (OSError, ValueError):
        return None
    return prov.get("scale") if isinstance(prov, dict) else None


def larger_figures(folder: Path, scale: str | None) -> list[tuple[str, str]]:
    """(name, its scale) of the figures directly in ``folder`` (named by their PNG; a sidecar
    without one, by itself) whose sidecars record a scale larger than ``scale``."""
    out = []
    for side in sorted(Path(folder).glob("*.provenance.json")):
        theirs = _recorded_figure_scale(side)
        if scale_rank(theirs) > scale_rank(scale):
            png = side.name.removesuffix(".provenance.json") + FIGURE_FORMATS[0]
            out.append((png if (side.parent / png).exists() else side.name, theirs))
    return out


def _refuse_larger(larger: list[tuple[str, str]], scale: str | None, param: str, path: Any,
                   what: str = "results") -> None:
    if larger:
        name, theirs = larger[0]
        more = f" and {len(larger) - 1} more" if len(larger) > 1 else ""
        raise UsageError(param, f"a folder without {what} of a larger scale than this run's "
                         f"({scale_text(scale)}): it holds {theirs}-scale {name}{more} "
                         "(--overwrite replaces them)", str(path))


def open_figures(path: str | Path, param: str, *, scale: str | None, overwrite: bool = False,
                 results: str | Path | None = None) -> Path:
    """The figures folder ``path`` of a driver at ``scale``, before any work: refused (UsageError
    naming ``param``) if it cannot be written, if it is the results folder ``results`` (a
    figure's sidecar has the name of its result's), if another process holds it (its
    :data:`FIGURES_LOCK`, held from here until :func:`release_results`), or if it holds figures
    of a larger scale than ``scale`` and ``overwrite`` is not given. Its figures may replace
    larger-scale ones from then on if ``overwrite`` (:func:`save_figure`)."""
    folder = check_writable_dir(path, param)
    if results is not None:
        require(folder.resolve() != Path(results).resolve(), param, "a folder other than "
                "--results-dir (a figure's sidecar, <stem>.provenance.json, has the name of its "
                "result's)", str(path))
    key, scale = folder.resolve(), run_scale(scale)
    with ExitStack() as stack:
        if key not in _figures_held:
            stack.enter_context(folder_lock(folder, FIGURES_LOCK, param, "a figures folder"))
        if not overwrite:
            _refuse_larger(larger_figures(folder, scale), scale, param, path, "figures")
        _session.push(stack.pop_all())
    _figures_held[key] = _figures_held.get(key, False) or overwrite
    return folder


def open_results(path: str | Path, param: str, *, scale: str | None,
                 overwrite: bool = False) -> Path:
    """The results folder ``path`` of a driver at ``scale``, held for this process until
    :func:`release_results` (the CLI releases it when the command ends). Refused (UsageError
    naming ``param``, before any work) if it cannot be written, if another process holds it, or
    if it holds results of a larger scale than ``scale`` and ``overwrite`` is not given. A folder
    this creates is removed again on release if nothing was written into it."""
    folder = check_writable_dir(path, param)
    key, scale = folder.resolve(), run_scale(scale)
    if key in _held:
        _held[key] = _held[key] or overwrite
        return folder
    with ExitStack() as stack:
        stack.enter_context(folder_lock(folder, RESULTS_LOCK, param, "a results folder"))
        if not overwrite:
            _refuse_larger(larger_results(folder, scale), scale, param, path)
        _session.push(stack.pop_all())
    _held[key] = overwrite
    return folder


def release_results() -> None:
    """Let go of every results folder this process holds (:func:`open_results`), and forget the
    figures folders it opened (:func:`open_figures`), the kernels its runs were trained under
    (:func:`~repro.runs.provenance.note_trained_under`) and how its run departs from its scale
    (:func:`~repro.runs.provenance.note_departures`)."""
    _held.clear()
    _figures_held.clear()
    forget_trained_under()
    forget_departures()
    _session.close()


def csv_bytes(frame: pd.DataFrame) -> bytes:
    """The bytes :func:`write_csv` writes for ``frame``."""
    return frame.to_csv(index=False, float_format=FLOAT_FORMAT, lineterminator="\n").encode()


def write_result(dest: str | Path, frame: pd.DataFrame, prov: dict[str, Any], *,
                 overwrite: bool = False) -> Path:
    """Write a result CSV and its provenance sidecar, both atomically, the sidecar recording the
    CSV's hash. The old sidecar goes first, so that a sidecar never describes a CSV it was not
    written with: an interrupted write leaves a CSV without a sidecar, which readers take for a
    missing result (:func:`read_result`); the old sidecar's notes go with it. A CSV that is
    already there byte for byte, with its sidecar, at ``prov``'s scale is kept with its first
    sidecar, and ``prov`` goes into a re-creation note beside it (:data:`RECREATION`). Refused
    (UsageError naming --results-dir) if ``dest`` holds a result of a larger scale than
    ``prov``'s, unless ``overwrite`` (or the folder was opened with it)."""
    dest = Path(dest)
    data = csv_bytes(frame)
    prov = {**prov, CSV_HASH: hashlib.sha256(data).hexdigest()}
    folder = dest.parent
    held = folder.resolve() in _held
    with (nullcontext() if held else folder_lock(folder, RESULTS_LOCK, "--results-dir",
                                                  "a results folder", wait=PAIR_WAIT)):
        theirs = _recorded_scale(dest)
        mine = prov.get("scale")
        if scale_rank(theirs) > scale_rank(mine) and not (overwrite or _held.get(folder.resolve())):
            _refuse_larger([(dest.name, theirs)], mine, "--results-dir", folder)
        if theirs == mine and _holds(dest, data):
            _note_recreation(sidecar_path(dest), prov)
            return dest
        sidecar_path(dest).unlink(missing_ok=True)
        for note in correction_paths(dest) + recreation_paths(dest):  # of the sidecar removed
            note.unlink()
        write_bytes(dest, data)
        write_json(sidecar_path(dest), prov)
    return dest


def _holds(dest: Path, data: bytes) -> bool:
    """Whether ``dest`` is already the CSV ``data``, with a sidecar that describes it."""
    try:
        if dest.read_bytes() != data:
            return False
        want = read_provenance(dest).get(CSV_HASH)
    except FileNotFoundError:
        return False
    return want in (None, hashlib.sha256(data).hexdigest())


RECREATION = "{stem}.recreated-{time}.json"
"""A re-creation note's name, beside the result ``<stem>.csv``; ``time``: YYYY-MM-DDTHHMMSSZ
(UTC), when the run that made the CSV again wrote it."""


def _stem(path: Path) -> str:
    """A result's or a figure's stem, from its CSV or its sidecar."""
    return path.name.removesuffix(".provenance.json").removesuffix(".csv")


def _note_recreation(side: Path, prov: dict[str, Any]) -> None:
    """Record, beside the sidecar ``side``, the run ``prov`` that made its files again byte for
    byte: a re-creation note named for this moment (:data:`RECREATION`)."""
    stamp = time.strftime("%Y-%m-%dT%H%M%SZ", time.gmtime())
    note = side.with_name(RECREATION.format(stem=_stem(side), time=stamp))
    write_json(note, {"recreates": side.name, **prov})


def recreation_paths(path: str | Path) -> list[Path]:
    """The re-creation notes of the sidecar of ``path`` (a result's CSV, or a figure's
    sidecar), oldest first."""
    path = Path(path)
    return sorted(path.parent.glob(RECREATION.format(stem=_stem(path), time="*")))


WRITER_MOMENT = 1.0
"""Seconds since a CSV or its folder last changed within which a reader that finds no sidecar
waits for one: a writer removes the old sidecar, writes the CSV, then the new sidecar at once
(:func:`write_result`); each step changes the folder."""


def read_result(result: str | Path) -> pd.DataFrame:
    """The table of a result whose sidecar belongs to it. FileNotFoundError (naming the file),
    which reads "not yet run", if the CSV or its sidecar is missing, or if the sidecar records
    another CSV's hash (a pair torn by a writer, or a CSV edited by hand); a writer at work is
    given a moment to finish its pair (a CSV without its sidecar, while the CSV or its folder
    changed within :data:`WRITER_MOMENT`). A sidecar without a hash is taken as it is (results
    written before the hash was recorded)."""
    result, side = Path(result), sidecar_path(result)
    for attempt in range(4):
        if attempt:
            time.sleep(0.05)
        try:
            before = side.read_bytes()
            data = result.read_bytes()
            if side.read_bytes() != before:
                continue  # rewritten meanwhile
        except FileNotFoundError:
            try:
                changed = max(result.stat().st_mtime, result.parent.stat().st_mtime)
            except FileNotFoundError:
                raise FileNotFoundError(errno.ENOENT, "missing", str(result)) from None
            if time.time() - changed > WRITER_MOMENT:
                break  # no writer is between the old sidecar's removal and the new one
            continue
        want = json.loads(before).get(CSV_HASH)
        if want is None or want == hashlib.sha256(data).hexdigest():
            import pandas as pd

            return pd.read_csv(io.BytesIO(data))
    if not side.exists():
        raise FileNotFoundError(errno.ENOENT, "missing", str(side))
    raise FileNotFoundError(errno.ENOENT, "not the CSV its sidecar describes", str(result))


CORRECTION = "{stem}.correction-{date}.json"
"""A correction note's name, beside the result ``<stem>.csv``; ``date``: YYYY-MM-DD."""


def correction_paths(result: str | Path) -> list[Path]:
    """The correction notes of ``result``'s sidecar, oldest first."""
    result = Path(result)
    return sorted(result.parent.glob(CORRECTION.format(stem=result.stem, date="*")))


def write_correction(result: str | Path, field: str, value: Any, reason: str,
                     date: str | None = None) -> Path:
    """Record that the sidecar of ``result`` holds a wrong ``field``, which should read ``value``,
    and why, in a new note dated ``date`` (default today, UTC); the sidecar stays as its run
    wrote it. A note is written once: UsageError if the field is not in the sidecar, or a note of
    that date exists."""
    prov = read_provenance(result)
    require(field in prov, "field", "a field of the sidecar: " + ", ".join(sorted(prov)), field)
    date = date or time.strftime("%Y-%m-%d", time.gmtime())
    note = Path(result).with_name(CORRECTION.format(stem=Path(result).stem, date=date))
    require(not note.exists(), "date", "a date without a correction note of this result yet",
            str(note))
    write_json(note, {"corrects": sidecar_path(result).name, "date": date, "field": field,
                      "recorded": prov[field], "value": value, "reason": reason})
    return note


def _corrections(result: str | Path) -> dict[str, Any]:
    """``{"corrections": [note, ...]}`` of ``result``'s correction notes, oldest first; empty if
    it has none."""
    notes = [json.loads(path.read_text()) for path in correction_paths(result)]
    return {"corrections": notes} if notes else {}


def _recreations(result: str | Path) -> dict[str, Any]:
    """``{"recreations": [note, ...]}`` of ``result``'s re-creation notes, oldest first; empty
    if it has none."""
    notes = [json.loads(path.read_text()) for path in recreation_paths(result)]
    return {"recreations": notes} if notes else {}


def shown_provenance(result: str | Path) -> dict[str, Any]:
    """The sidecar of ``result`` as its run wrote it, with its correction notes under
    ``corrections`` and its re-creation notes under ``recreations`` where it has any: a reader
    sees both the recorded and the corrected value of a field, and every later run that made the
    same bytes."""
    return {**read_provenance(result), **_corrections(result), **_recreations(result)}


def read_provenance(result: str | Path) -> dict[str, Any]:
    """The provenance sidecar of a result; FileNotFoundError (naming the sidecar) if the result or
    its sidecar is missing: a CSV whose write was interrupted has none and counts as missing."""
    result, side = Path(result), sidecar_path(result)
    for path in (result, side):
        if not path.exists():
            raise FileNotFoundError(2, "missing", str(path))
    return json.loads(side.read_text())
