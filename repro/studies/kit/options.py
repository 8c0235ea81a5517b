"""Command-line options every driver shares, and where a driver writes by default."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, Callable

from repro.core.config import DEFAULT_SCALE, SCALES, for_scale
from repro.core.errors import require
from repro.runs.provenance import note_departures
from repro.runs.results import open_figures, open_results


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
                        help="replace results (and figures) of a larger scale in --results-dir "
                             "(--figures-dir; their sidecars say which; without it such a folder "
                             "is refused)")
    if figures:
        parser.add_argument("--figures-dir", help="folder for PNG and PDF figures and their "
                            "provenance sidecars (default figures/<scale>)")


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


NEUTRAL = ("help", "config", "scale", "seed", "results_dir", "figures_dir", "runs_dir",
           "overwrite", "n_jobs", "scheduler", "no_figure", "replot")
"""Options that leave a run's numbers as the scale makes them: where files go, how many
processes compute them, the root seed."""
VARIANTS = ("learner",)
"""Options that choose which study a driver runs, and so which result files it writes (the
suite's learner: ``*_suite``), rather than its settings; a driver module names its own further
ones in a ``VARIANTS`` tuple (``fig-transfer --sim-version``: ``*_20170422``)."""


def scale_departures(parser: argparse.ArgumentParser, args: argparse.Namespace,
                     variants: tuple[str, ...] = ()) -> list[str]:
    """The options (their flags) whose values in ``args`` are not those of ``--scale``: a config
    field's flag given with another value than the scale's, any other option that is not
    :data:`NEUTRAL` nor a variant (:data:`VARIANTS` and ``variants``) given with another value
    than its default. A run with any is not a run of its scale
    (:func:`repro.runs.provenance.run_scale`)."""
    out = []
    for action in parser._actions:
        dest = action.dest
        if dest in (*NEUTRAL, *VARIANTS, *variants) or not hasattr(args, dest):
            continue
        setting = getattr(action, "setting", None)  # (config class, field): add_config_arguments
        expected = (getattr(for_scale(setting[0], args.scale), setting[1]) if setting
                    else action.default)
        if _comparable(getattr(args, dest)) != _comparable(expected):
            out.append(action.option_strings[0])
    return out


def _comparable(value: object) -> object:
    return tuple(value) if isinstance(value, list) else value


def note_scale_departures(module: object, parser: argparse.ArgumentParser,
                          args: argparse.Namespace) -> None:
    """Note, for the sidecars and the guards of this run, the options by which a driver's run
    departs from its ``--scale`` (:func:`scale_departures`)."""
    if hasattr(args, "scale") and hasattr(args, "results_dir"):
        note_departures(scale_departures(parser, args, getattr(module, "VARIANTS", ())))


def results_folder(args: argparse.Namespace) -> Path:
    """The driver's ``--results-dir``, checked and held until the command ends: writable, no other
    process writing to it, and no results of a larger scale than ``--scale`` there unless
    ``--overwrite`` (:func:`repro.runs.results.open_results`)."""
    return open_results(args.results_dir, "--results-dir", scale=args.scale,
                        overwrite=args.overwrite)


def figures_folder(args: argparse.Namespace, scale: str | None = None) -> Path:
    """The driver's ``--figures-dir``, checked before any work: writable, not ``--results-dir``,
    and no figures of a larger scale than the run's (``scale``, default ``--scale``; a replot's
    is its results') there unless ``--overwrite`` (:func:`repro.runs.results.open_figures`)."""
    return open_figures(args.figures_dir, "--figures-dir",
                        scale=args.scale if scale is None else scale, overwrite=args.overwrite,
                        results=args.results_dir)


def replot_figures(args: argparse.Namespace, *names: str) -> tuple[Path, list[Path]]:
    """``--replot``'s figures folder (:func:`figures_folder` at the scale of the results it
    draws) and the paths of those results, ``names`` in ``--results-dir``, the sources of its
    figure (read them with :func:`read_for_replot` first)."""
    from repro.runs.results import figure_scale, source_records

    sources = [Path(args.results_dir) / name for name in names]
    return figures_folder(args, figure_scale(source_records(sources[:1]))), sources



def replot_pair(args: argparse.Namespace, stem: str, title: Callable[[dict[str, Any]], str],
                plot: Callable[..., None]) -> int:
    """``--replot`` of a study whose results are ``<stem>.csv`` and ``<stem>_summary.csv``: its
    figure ``<stem>`` drawn again from them, ``plot(table, summary, figure stem, title, sources)``,
    titled from what their sidecar records (``title(provenance)``)."""
    from repro.runs.results import read_provenance

    names = (f"{stem}.csv", f"{stem}_summary.csv")
    table, summary = read_for_replot(args, *names)
    text = title(read_provenance(Path(args.results_dir) / names[0]))
    figures, sources = replot_figures(args, *names)
    plot(table, summary, figures / stem, text, sources)
    print(f"wrote {figures / stem}.png/.pdf")
    return 0

def add_replot(parser: argparse.ArgumentParser) -> None:
    """``--replot``: a figure drawn again from its driver's result CSVs, without rerunning."""
    parser.add_argument("--replot", action="store_true", help="draw the figure again from the "
                        "results in --results-dir (nothing is run or written but the figure)")


def read_for_replot(args: argparse.Namespace, *names: str) -> list:
    """The result tables ``names`` in ``--results-dir`` that ``--replot`` draws from; a
    UsageError naming ``--replot`` if one is missing (or torn from its sidecar)."""
    from repro.core.errors import UsageError
    from repro.runs.results import read_result

    folder = Path(args.results_dir)
    tables = []
    for name in names:
        try:
            tables.append(read_result(folder / name))
        except FileNotFoundError as err:
            raise UsageError("--replot", f"the results of an earlier run in {folder}",
                             f"{err.strerror}: {err.filename}") from None
    return tables
