"""Command-line options every driver shares, and where a driver writes by default."""

from __future__ import annotations

import argparse
from pathlib import Path

from repro.core.config import DEFAULT_SCALE, SCALES
from repro.core.errors import require
from repro.core.io import open_results


def add_common(parser: argparse.ArgumentParser, *, seed: int | None = 0,
               figures: bool = True) -> None:
    """Options every driver takes: scale, seed (``None``: the driver has no randomness) and where
    results and figures (for drivers that draw some) go."""
    parser.add_argument("--scale", default=DEFAULT_SCALE, help=f"one of {', '.join(SCALES)}")
    if seed is not None:
        parser.add_argument("--seed", type=int, default=seed,
                            help="root seed of every random stream (an integer >= 0)")
    parser.add_argument("--results-dir",
                        help="folder for CSVs and sidecars (default results/<scale>)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace results of a larger scale in --results-dir (their sidecars "
                             "say which; without it such a folder is refused)")
    if figures:
        parser.add_argument("--figures-dir", help="folder for PNG and PDF figures "
                            "(default figures/<scale>)")


def scale_folder(kind: str, scale: str) -> Path:
    """Where the results (``kind`` "results") or figures of ``scale`` go by default: each scale
    has its own folder, so that a smaller scale never overwrites a larger one's files."""
    require(scale in SCALES, "--scale", "one of " + ", ".join(SCALES), scale)
    return Path(kind) / scale


def default_folders(args: argparse.Namespace) -> None:
    """Drivers (the commands with a ``--scale``) write into their scale's folders by default."""
    for kind in ("results", "figures"):
        if hasattr(args, "scale") and getattr(args, f"{kind}_dir", "") is None:
            setattr(args, f"{kind}_dir", str(scale_folder(kind, args.scale)))


def results_folder(args: argparse.Namespace) -> Path:
    """The driver's ``--results-dir``, checked and held until the command ends: writable, no other
    process writing to it, and no results of a larger scale than ``--scale`` there unless
    ``--overwrite`` (:func:`repro.core.io.open_results`)."""
    return open_results(args.results_dir, "--results-dir", scale=args.scale,
                        overwrite=args.overwrite)
