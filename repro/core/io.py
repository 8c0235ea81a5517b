"""Atomic, deterministic result files and their provenance sidecars.

Every result is written to a temporary file in the destination folder and renamed into place, so an
interrupted run never leaves a half-written file. CSVs are written with a fixed float format, so the
same computation gives byte-identical files.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from importlib import metadata
from pathlib import Path
from typing import Any, Iterator

import pandas as pd

from repro.core.errors import UsageError, require

NAME_MAX = 255
"""The longest file or folder name (bytes) Linux and macOS file systems take."""

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
    """``path``, unless one of its names is longer than a file system takes (UsageError)."""
    long = next((part for part in Path(path).parts if len(part.encode()) > NAME_MAX), None)
    require(long is None, param, f"a path whose names have at most {NAME_MAX} bytes",
            f"{long[:20]}... ({len(long.encode())} bytes)" if long else None)
    return Path(path)


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
    with dest.open("a", newline="") as f:
        frame.to_csv(f, header=new, index=False, float_format=FLOAT_FORMAT, lineterminator="\n")


def save_figure(fig: Any, stem: str | Path) -> list[Path]:
    """Lay ``fig`` out, write ``stem.png`` and ``stem.pdf`` atomically (PDF without a timestamp, so
    it is stable), and close it."""
    import matplotlib.pyplot as plt  # loaded already by the caller that drew ``fig``

    fig.tight_layout()
    out = []
    for ext, kw in ((".png", {"dpi": 150}), (".pdf", {"metadata": {"CreationDate": None}})):
        dest = Path(str(stem) + ext)
        with atomic_path(dest) as tmp:
            fig.savefig(tmp, format=ext[1:], bbox_inches="tight", **kw)
        out.append(dest)
    plt.close(fig)
    return out


OUTPUTS = ("results", "figures", "paper_claims.md")
"""What the drivers write: changes there do not make a working tree dirty."""


def git_commit(root: Path | None = None) -> str:
    """The commit of the working tree at ``root`` (default: this suite's), with ``+dirty`` if it has
    uncommitted changes outside :data:`OUTPUTS` (otherwise the second driver run after a commit
    would already be "dirty")."""
    root = root or Path(__file__).resolve().parents[2]
    try:
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
    """What the numbers may depend on beyond the code: training results are byte-identical on one
    CPU model but not across CPUs, because torch picks its vectorised kernels (and so its rounding)
    by what the CPU supports (docs/performance.md, "Determinism across machines")."""
    out: dict[str, Any] = {"platform": platform.platform(), "cpus": os.cpu_count(),
                           "cpu": cpu_model()}
    torch = sys.modules.get("torch")  # not imported here: drivers without torch stay light
    if torch is not None:
        out["torch_cpu_capability"] = torch.backends.cpu.get_cpu_capability()
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
    """The sidecar content: what was run, on what, from which commit, and how long it took
    (``scale`` None where the config alone says what was run, as for a training run)."""
    from repro.core.config import to_dict

    rec = {
        "command": command,
        "argv": sys.argv,
        "scale": scale,
        "seed": seed,
        "config": to_dict(config) if hasattr(config, "__dataclass_fields__") else config,
        "git_commit": git_commit(),
        "versions": versions(),
        "machine": machine(),
        "wall_seconds": round(wall_seconds, 3),
        "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    if extra:
        rec.update(extra)
    return rec


def sidecar_path(result: str | Path) -> Path:
    """``results/x.csv`` -> ``results/x.provenance.json``."""
    result = Path(result)
    return result.with_name(result.stem + ".provenance.json")


def write_result(dest: str | Path, frame: pd.DataFrame, prov: dict[str, Any]) -> Path:
    """Write a result CSV and its provenance sidecar, both atomically. The old sidecar goes first,
    so that a sidecar never describes a CSV it was not written with: an interrupted write leaves a
    CSV without a sidecar, which readers take for a missing result (:func:`read_result`)."""
    sidecar_path(dest).unlink(missing_ok=True)
    write_csv(dest, frame)
    write_json(sidecar_path(dest), prov)
    return Path(dest)


def read_provenance(result: str | Path) -> dict[str, Any]:
    """The provenance sidecar of a result; FileNotFoundError (naming the sidecar) if the result or
    its sidecar is missing: a CSV whose write was interrupted has none and counts as missing."""
    result, side = Path(result), sidecar_path(result)
    for path in (result, side):
        if not path.exists():
            raise FileNotFoundError(2, "missing", str(path))
    return json.loads(side.read_text())
