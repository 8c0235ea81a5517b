"""Command-line options every driver shares, what they resolve to (`Folders`, `Workers`, `Command`:
the frozen records a driver's `run` reads), and where a driver writes by default."""

from __future__ import annotations

import argparse
import os
import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Generic, TypeVar

from repro.core.config import DEFAULT_SCALE, SCALES, for_scale
from repro.core.errors import UsageError, require
from repro.runs.files import check_writable_dir
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


@dataclass(frozen=True)
class Folders:
    """Where a driver reads and writes, resolved once from its options by the command line
    (:meth:`of`); nothing below the command line reads a folder from the parsed options."""

    scale: str
    """The scale of what the driver writes (``--scale``)."""
    results: Path
    """CSVs and their sidecars (``--results-dir``; default results/<scale>)."""
    figures: Path | None
    """PNG and PDF figures and their sidecars (``--figures-dir``; default figures/<scale>); None
    for a driver that draws none."""
    runs: Path | None
    """The training runs' folders (``--runs-dir``); None for a driver that trains none."""
    overwrite: bool
    """Whether results and figures of a larger scale there may be replaced (``--overwrite``)."""

    @classmethod
    def of(cls, args: argparse.Namespace) -> Folders | None:
        """The folders a driver's options name, each defaulting to its scale's own
        (:func:`scale_folder`); None for a command that is no driver (without both ``--scale``
        and ``--results-dir``)."""
        if not (hasattr(args, "scale") and hasattr(args, "results_dir")):
            return None

        def named(kind: str) -> Path | None:
            if not hasattr(args, f"{kind}_dir"):
                return None
            given = getattr(args, f"{kind}_dir")
            return scale_folder(kind, args.scale) if given is None else Path(given)

        return cls(scale=args.scale, results=named("results"), figures=named("figures"),
                   runs=named("runs"), overwrite=bool(getattr(args, "overwrite", False)))

    def within(self, name: str) -> Folders:
        """These folders with the results and the figures in their subfolders ``name`` (the runs
        where they are)."""
        return replace(
            self, results=self.results / name,
            figures=None if self.figures is None else self.figures / name)

    def open_results(self) -> Path:
        """The results folder, checked and held until the command ends: writable, no other
        process writing to it, and no results of a larger scale than :attr:`scale` there unless
        :attr:`overwrite` (:func:`repro.runs.results.open_results`)."""
        return open_results(self.results, "--results-dir", scale=self.scale,
                            overwrite=self.overwrite)

    def open_figures(self, scale: str | None = None) -> Path:
        """The figures folder, checked before any work: writable, not the results folder, and no
        figures of a larger scale than the run's (``scale``, default :attr:`scale`; a replot's is
        its results') there unless :attr:`overwrite` (:func:`repro.runs.results.open_figures`)."""
        assert self.figures is not None, "a driver that draws no figure opened its folder"
        return open_figures(self.figures, "--figures-dir",
                            scale=self.scale if scale is None else scale,
                            overwrite=self.overwrite, results=self.results)

    def run_root(self, *parts: str) -> Path:
        """The folder ``parts`` under the runs folder where a study keeps its run folders,
        created and checked writable (``--runs-dir``)."""
        assert self.runs is not None, "a driver that trains nothing asked for its runs folder"
        return check_writable_dir(self.runs.joinpath(*parts), "--runs-dir")

    def open(self) -> tuple[Path, Path]:
        """The results and figures folders of a driver that draws figures, checked before any
        work (:meth:`open_figures`, then :meth:`open_results`)."""
        figures = self.open_figures()
        return self.open_results(), figures


_ADDRESS = re.compile(r"(?:(tcp|tls)://)?(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9](?:[A-Za-z0-9.-]*"
                      r"[A-Za-z0-9])?):([0-9]{1,5})")
SCHEDULER_FORM = "the address of a running Dask scheduler, tcp://HOST:PORT (or tls://)"


def check_scheduler(scheduler: str) -> tuple[str, str, int]:
    """(scheme, host, port) of a ``--scheduler`` address in the form tcp://HOST:PORT, tls://HOST:PORT
    or HOST:PORT; a UsageError otherwise, before any connection is tried."""
    m = _ADDRESS.fullmatch(scheduler)
    port = int(m.group(3)) if m else 0
    if not m or not 1 <= port <= 65535:
        raise UsageError("--scheduler", SCHEDULER_FORM, scheduler)
    return m.group(1) or "tcp", m.group(2).strip("[]"), port


@dataclass(frozen=True)
class Workers:
    """Where a driver's parallel work runs (training runs, policy tests, Monte Carlo cells),
    checked once by the command line (:meth:`of`)."""

    n_jobs: int | None = None
    """joblib worker processes (``--n-jobs``; None: one per core)."""
    scheduler: str | None = None
    """The address of an existing Dask scheduler to run on instead (``--scheduler``)."""

    @property
    def processes(self) -> int:
        """The most joblib worker processes to start."""
        return self.n_jobs or os.cpu_count() or 1

    @classmethod
    def of(cls, args: argparse.Namespace) -> Workers:
        """The workers a driver's options name (a UsageError naming the flag if one is bad); the
        default workers for a driver without such options."""
        n_jobs, scheduler = getattr(args, "n_jobs", None), getattr(args, "scheduler", None)
        require(n_jobs is None or n_jobs >= 1, "--n-jobs", "an integer >= 1", n_jobs)
        if scheduler is not None:
            check_scheduler(scheduler)
        return cls(n_jobs=n_jobs, scheduler=scheduler)


EVERY_CORE = Workers()
"""A joblib worker process per core (no ``--n-jobs``, no ``--scheduler``)."""
ONE_PROCESS = Workers(n_jobs=1)
"""One joblib worker process."""

C = TypeVar("C")


@dataclass(frozen=True)
class Command(Generic[C]):
    """A driver's options, resolved once by the command line (:meth:`of`): with
    :class:`Folders`, everything a driver's ``run`` reads."""

    study: C
    """The study's own settings: a frozen config (what the driver's sidecars record)."""
    seed: int | None = None
    """The root seed of every random stream (``--seed``); None for a driver without one."""
    workers: Workers = EVERY_CORE
    """Where its parallel work runs (``--n-jobs``, ``--scheduler``)."""
    replot: bool = False
    """Draw the figure again from the results there and run nothing (``--replot``)."""
    figure: bool = True
    """Draw the figure (off: ``--no-figure``)."""

    @classmethod
    def of(cls, args: argparse.Namespace, study: C) -> Command[C]:
        """The command of a driver's parsed options and its ``study`` settings (made from them by
        the driver's ``configure``)."""
        return cls(study=study, seed=getattr(args, "seed", None), workers=Workers.of(args),
                   replot=bool(getattr(args, "replot", False)),
                   figure=not getattr(args, "no_figure", False))


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
    field's flag given with another value than the scale's (or than the command's own default
    of it, ``add_config_arguments(defaults=...)``), any other option that is not
    :data:`NEUTRAL` nor a variant (:data:`VARIANTS` and ``variants``) given with another value
    than its default. A run with any is not a run of its scale
    (:func:`repro.runs.provenance.run_scale`)."""
    out = []
    for action in parser._actions:
        dest = action.dest
        if dest in (*NEUTRAL, *VARIANTS, *variants) or not hasattr(args, dest):
            continue
        setting = getattr(action, "setting", None)  # (config class, field): add_config_arguments
        if hasattr(action, "own_default"):
            expected = action.own_default
        elif setting:
            expected = getattr(for_scale(setting[0], args.scale), setting[1])
        else:
            expected = action.default
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


def replot_figures(folders: Folders, *names: str) -> tuple[Path, list[Path]]:
    """``--replot``'s figures folder (:meth:`Folders.open_figures` at the scale of the results it
    draws) and the paths of those results, ``names`` in the results folder, the sources of its
    figure (read them with :func:`read_for_replot` first)."""
    from repro.runs.results import figure_scale, source_records

    sources = [folders.results / name for name in names]
    return folders.open_figures(figure_scale(source_records(sources[:1]))), sources



def replot_pair(folders: Folders, stem: str, title: Callable[[dict[str, Any]], str],
                plot: Callable[..., None]) -> int:
    """``--replot`` of a study whose results are ``<stem>.csv`` and ``<stem>_summary.csv``: its
    figure ``<stem>`` drawn again from them, ``plot(table, summary, figure stem, title, sources)``,
    titled from what their sidecar records (``title(provenance)``)."""
    from repro.runs.results import read_provenance

    names = (f"{stem}.csv", f"{stem}_summary.csv")
    table, summary = read_for_replot(folders, *names)
    text = title(read_provenance(folders.results / names[0]))
    figures, sources = replot_figures(folders, *names)
    plot(table, summary, figures / stem, text, sources)
    print(f"wrote {figures / stem}.png/.pdf")
    return 0

def add_replot(parser: argparse.ArgumentParser) -> None:
    """``--replot``: a figure drawn again from its driver's result CSVs, without rerunning."""
    parser.add_argument("--replot", action="store_true", help="draw the figure again from the "
                        "results in --results-dir (nothing is run or written but the figure)")


def read_for_replot(folders: Folders, *names: str) -> list:
    """The result tables ``names`` in the results folder that ``--replot`` draws from; a
    UsageError naming ``--replot`` if one is missing (or torn from its sidecar)."""
    from repro.core.errors import UsageError
    from repro.runs.results import read_result

    folder = folders.results
    tables = []
    for name in names:
        try:
            tables.append(read_result(folder / name))
        except FileNotFoundError as err:
            raise UsageError("--replot", f"the results of an earlier run in {folder}",
                             f"{err.strerror}: {err.filename}") from None
    return tables
