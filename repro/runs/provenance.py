"""What a result's sidecar records of the run that made it: the command, its config, the commit,
the versions of the packages, the machine and its kernels, and the training runs it rests on."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path
from typing import Any, Sequence

from repro.core.config import SCALES
from repro.runs.cpu import cpu_model

PROVENANCE_PACKAGES = (
    "numpy", "scipy", "torch", "simpy", "pandas", "statsmodels", "numba", "matplotlib",
    "pettingzoo",
)


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
    """What the numbers may depend on beyond the code: the CPU, and where torch is loaded or the
    results rest on trained runs (:func:`note_trained_under`; a sweep's parent process may leave
    torch to its workers) the kernels torch, its MKL and numpy compute with (``kernels``: pinned
    to AVX2 on x86-64 CPUs with AVX2, so that training is byte-identical across them; see
    :mod:`repro.runs.kernels`)."""
    out: dict[str, Any] = {"platform": platform.platform(), "cpus": os.cpu_count(),
                           "cpu": cpu_model()}
    torch = sys.modules.get("torch")  # not imported for drivers without it: they stay light
    if torch is None and _trained_under:
        import torch
    if torch is not None:
        from repro.runs.kernels import state

        out["torch_cpu_capability"] = torch.backends.cpu.get_cpu_capability()
        out["kernels"] = state()
    return out


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
    (:func:`repro.runs.run_folder.recorded_kernels`) until :func:`release_results`."""
    _trained_under[json.dumps(kernels, sort_keys=True)] = kernels


def forget_trained_under() -> None:
    """Forget what :func:`note_trained_under` noted (the command has ended)."""
    _trained_under.clear()


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


CUSTOM = "custom"
"""The scale a run records that was started at the paper scale with settings of its own."""
_departures: list[str] = []
"""The options by which this process's run departs from its ``--scale``
(:func:`note_departures`)."""


def note_departures(flags: Sequence[str]) -> None:
    """Note that this process's run departs from its ``--scale`` by the options ``flags`` (the CLI
    notes them before a driver runs; :func:`forget_departures` forgets them)."""
    _departures[:] = list(flags)


def forget_departures() -> None:
    """Forget what :func:`note_departures` noted (a command's end)."""
    _departures.clear()


def run_scale(scale: str | None) -> str | None:
    """The scale this process's results are of: ``scale``, or :data:`CUSTOM` where that is the
    paper scale and the run departs from its settings (:func:`note_departures`)."""
    return CUSTOM if scale == SCALES[-1] and _departures else scale


def scale_text(scale: str | None) -> str:
    """A run's scale as a refusal names it, with what made a paper-scale run a custom one."""
    if scale == CUSTOM and _departures:
        return f"{CUSTOM}: {', '.join(_departures)} differ from the {SCALES[-1]} scale's"
    return str(scale)
