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
  (:func:`write_correction`), and :func:`shown_provenance` shows the sidecar with its notes.
- **The paper scale is what was run, not what was asked.** A run started with ``--scale paper``
  and settings of its own (``race --scale paper --n-sets 10``) records the scale ``custom``
  (:func:`run_scale`), below every scale: it neither replaces paper-scale results nor counts as
  one for the claims.

Figures are guarded the same way. A figure is ``<stem>.png`` and ``<stem>.pdf`` with a sidecar,
``<stem>.provenance.json``, that records both files' SHA-256, the result CSVs it was drawn from
(each with its hash and scale) and the scale (:func:`save_figure`). A driver checks its figures
folder for figures of a larger scale before any work (:func:`open_figures`), and a figure is not
replaced by one of a smaller scale unless told to; figures without a sidecar are replaced. A
figure's sidecar has the name of its stem's result's, so a figures folder is never the results
folder.
"""

from __future__ import annotations

import errno
import hashlib
import io
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from contextlib import ExitStack, contextmanager, nullcontext
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterator, Sequence

from repro.core.config import SCALES
from repro.core.errors import UsageError, require
from repro.core.locks import folder_lock

if TYPE_CHECKING:  # pandas is imported where a table is written or read: the CLI starts lighter
    import pandas as pd

NAME_MAX = 255
"""The longest file or folder name (bytes) Linux and macOS file systems take."""
PATH_MAX = 4096
"""The longest path (bytes, with its terminating zero byte) Linux takes; macOS takes 1024."""

FLOAT_FORMAT = "%.10g"
"""Ten significant digits: well above every quantity's precision, and stable across platforms."""

PROVENANCE_PACKAGES = (
    "numpy", "scipy", "torch", "simpy", "pandas", "statsmodels", "numba", "matplotlib",
    "pettingzoo",
)


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
    sidecar never describes files it was not written with."""
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
        figure_sidecar(stem).unlink(missing_ok=True)
        for dest, data in files.items():
            write_bytes(dest, data)
        write_json(figure_sidecar(stem), {
            "command": records[0]["command"] if records else None,
            "scale": mine,
            "figures": {dest.name: hashlib.sha256(data).hexdigest()
                        for dest, data in files.items()},
            "sources": records,
            **run_record(),
            **(extra or {}),
        })
    return list(files)


OUTPUTS = ("results", "figures", "paper_claims.md")
"""What the drivers write: changes there do not make a working tree dirty."""


def git_commit(root: Path | None = None) -> str:
    """The commit of the working tree at ``root`` (default: this suite's), with ``+dirty`` if it has
    uncommitted changes outside :data:`OUTPUTS` (otherwise the second driver run after a commit
    would already be "dirty"); "unknown" where ``root`` is not the top of a git working tree (an
    exported or installed copy of the suite, which git would take for part of an enclosing
    repository, whose commit says nothing of this code)."""
    root = (root or Path(__file__).resolve().parents[2]).resolve()
    try:
        top = subprocess.run(["git", "rev-parse", "--show-toplevel"], cwd=root,
                             capture_output=True, text=True, check=True).stdout.strip()
        if Path(top).resolve() != root:
            return "unknown"
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True,
                             check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".",
                                *(f":(exclude){p}" for p in OUTPUTS)], cwd=root,
                               capture_output=True, text=True, check=True).stdout.strip()
        return sha + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for name in PROVENANCE_PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def machine() -> dict[str, Any]:
    """What the numbers may depend on beyond the code: the CPU, and where torch is loaded the
    kernels torch, its MKL and numpy compute with (``kernels``: pinned to AVX2 on x86-64 CPUs with
    AVX2, so that training is byte-identical across them; see :mod:`repro.core.kernels`)."""
    out: dict[str, Any] = {"platform": platform.platform(), "cpus": os.cpu_count(),
                           "cpu": cpu_model()}
    torch = sys.modules.get("torch")  # not imported here: drivers without torch stay light
    if torch is not None:
        from repro.core.kernels import state

        out["torch_cpu_capability"] = torch.backends.cpu.get_cpu_capability()
        out["kernels"] = state()
    return out


def cpu_model() -> str:
    """The CPU's name with its family and model numbers (a VM's name alone is often generic)."""
    try:
        with open("/proc/cpuinfo") as f:
            fields = dict(line.split(":", 1) for line in f.read().split("\n\n")[0].splitlines()
                          if ":" in line)
    except OSError:
        return platform.processor() or "unknown"
    fields = {k.strip(): v.strip() for k, v in fields.items()}
    return (f"{fields.get('model name', 'unknown')} (family {fields.get('cpu family', '?')}, "
            f"model {fields.get('model', '?')})")


def provenance(config: Any, *, command: str, scale: str | None, seed: int | None,
               wall_seconds: float, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """The sidecar content: what was run, on what, from which commit, how long it took (``scale``
    None where the config alone says what was run, as for a training run), and the kernels of the
    training runs it rests on (:func:`note_trained_under`)."""
    from repro.core.config import to_dict

    rec = {
        "command": command,
        "scale": run_scale(scale),
        "seed": seed,
        "config": to_dict(config) if hasattr(config, "__dataclass_fields__") else config,
        "wall_seconds": round(wall_seconds, 3),
        **run_record(),
    }
    if rec["scale"] == CUSTOM:
        rec["departs_from_scale"] = {"scale": scale, "options": list(_departures)}
    if _trained_under:
        rec["trained_under"] = [_trained_under[key] for key in sorted(_trained_under)]
    if extra:
        rec.update(extra)
    return rec


_trained_under: dict[str, Any] = {}
"""The kernels that the training runs this command's results rest on were trained with (each
distinct record once, by its JSON text; None for runs that recorded none), as the sweeps note
them (:func:`note_trained_under`); a result's sidecar names them as ``trained_under``."""


def note_trained_under(kernels: dict[str, Any] | None) -> None:
    """Note that a result of this command rests on a run trained under ``kernels``
    (:func:`repro.learn.run_folder.recorded_kernels`) until :func:`release_results`."""
    _trained_under[json.dumps(kernels, sort_keys=True)] = kernels


def run_record() -> dict[str, Any]:
    """What every sidecar (a result's, a figure's) records of the process that wrote it: its
    command line, the commit, the versions, the machine and the time it finished."""
    return {
        "argv": sys.argv,
        "git_commit": git_commit(),
        "versions": versions(),
        "machine": machine(),
        "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }


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


CUSTOM = "custom"
"""The scale a run records that was started at the paper scale with settings of its own."""
_departures: list[str] = []
"""The options by which this process's run departs from its ``--scale``
(:func:`note_departures`)."""


def note_departures(flags: Sequence[str]) -> None:
    """Note that this process's run departs from its ``--scale`` by the options ``flags`` (the CLI
    notes them before a driver runs; :func:`release_results` forgets them)."""
    _departures[:] = list(flags)


def run_scale(scale: str | None) -> str | None:
    """The scale this process's results are of: ``scale``, or :data:`CUSTOM` where that is the
    paper scale and the run departs from its settings (:func:`note_departures`)."""
    return CUSTOM if scale == SCALES[-1] and _departures else scale


def _scale_text(scale: str | None) -> str:
    """A run's scale as a refusal names it, with what made a paper-scale run a custom one."""
    if scale == CUSTOM and _departures:
        return f"{CUSTOM}: {', '.join(_departures)} differ from the {SCALES[-1]} scale's"
    return str(scale)


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
                         f"({_scale_text(scale)}): it holds {theirs}-scale {name}{more} "
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
    (:func:`note_trained_under`) and how its run departs from its scale
    (:func:`note_departures`)."""
    _held.clear()
    _figures_held.clear()
    _trained_under.clear()
    _departures.clear()
    _session.close()


def csv_bytes(frame: pd.DataFrame) -> bytes:
    """The bytes :func:`write_csv` writes for ``frame``."""
    return frame.to_csv(index=False, float_format=FLOAT_FORMAT, lineterminator="\n").encode()


def write_result(dest: str | Path, frame: pd.DataFrame, prov: dict[str, Any], *,
                 overwrite: bool = False) -> Path:
    """Write a result CSV and its provenance sidecar, both atomically, the sidecar recording the
    CSV's hash. The old sidecar goes first, so that a sidecar never describes a CSV it was not
    written with: an interrupted write leaves a CSV without a sidecar, which readers take for a
    missing result (:func:`read_result`). Refused (UsageError naming --results-dir) if ``dest``
    holds a result of a larger scale than ``prov``'s, unless ``overwrite`` (or the folder was
    opened with it)."""
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
        sidecar_path(dest).unlink(missing_ok=True)
        write_bytes(dest, data)
        write_json(sidecar_path(dest), prov)
    return dest


def read_result(result: str | Path) -> pd.DataFrame:
    """The table of a result whose sidecar belongs to it. FileNotFoundError (naming the file),
    which reads "not yet run", if the CSV or its sidecar is missing, or if the sidecar records
    another CSV's hash (a pair torn by a writer, or a CSV edited by hand); a writer at work is
    given a moment to finish its pair. A sidecar without a hash is taken as it is (results
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
            if not result.exists():
                raise FileNotFoundError(errno.ENOENT, "missing", str(result)) from None
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


def shown_provenance(result: str | Path) -> dict[str, Any]:
    """The sidecar of ``result`` as its run wrote it, with its correction notes under
    ``corrections`` where it has any: a reader sees both the recorded and the corrected value of
    a field."""
    return {**read_provenance(result), **_corrections(result)}


def read_provenance(result: str | Path) -> dict[str, Any]:
    """The provenance sidecar of a result; FileNotFoundError (naming the sidecar) if the result or
    its sidecar is missing: a CSV whose write was interrupted has none and counts as missing."""
    result, side = Path(result), sidecar_path(result)
    for path in (result, side):
        if not path.exists():
            raise FileNotFoundError(2, "missing", str(path))
    return json.loads(side.read_text())
