"""``python -m repro reproduce``: every study of the paper and beyond at one scale, then their
verdicts (``claims``); what ``make reproduce`` runs.

Each study runs as its own command would (:data:`STUDIES`: the command line of each, given the
same scale, seed and folders), so its results are the same bytes, but the training runs of all
of them are trained together, so that no core idles while runs remain:

1. Each study is started in the order of :data:`STUDIES` and runs to its end until one reaches a
   sweep with runs to train (:func:`repro.studies.kit.sweep.planning`); from there on every
   later study that trains is only planned: started and stopped at its first sweep, whose runs
   to train join the plan, before it does any work. A study that stops earlier, for want of
   another's results (the bus curves need the thresholds, the bus pictures the lambda sweep's
   best run), waits for the next round.
2. The plan's runs, from every study, are trained in one pool, longest first, each run once
   where studies share it (:func:`repro.studies.kit.sweep.train_runs`).
3. Repeat from 1 with the studies not yet finished, until none is left (a study with several
   sweeps, or one that waited, plans more in a later round).

The first study of a round runs to its end, plans runs or fails (its error ends the command), so
every round moves on. Every run is checkpointed, so the same command run again resumes where it
stopped and trains nothing twice (the studies that had finished test their policies again). The
rounds' timings go to ``reproduce_timing.csv``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import time
from dataclasses import dataclass

import pandas as pd

from repro import cli
from repro.core.config import Validated, add_config_arguments, for_scale, given_fields
from repro.runs.provenance import provenance
from repro.runs.results import write_result
from repro.studies.kit.options import Command, Folders, Workers, add_common
from repro.studies.kit.sweep import Planned, add_sweep_arguments, planning, train_runs

BUS_PANELS = ("nohold", "authors", "thresholds", "mlp", "gru", "gru-greedy")
"""The bus pictures' panels: the paper's, and the released GRU policy that drew them (C5 is
decided on it; its runs are trained by the first of the two pictures)."""

STUDIES: dict[str, tuple[str, ...]] = {
    "race": ("race",),
    "bus-thresholds": ("bus-thresholds",),
    "bus-lambda": ("bus-lambda",),
    "bus-batch": ("bus-batch",),
    "bus-lambda-pool": ("bus-lambda", "--sampler", "released-pool"),
    "bus-batch-pool": ("bus-batch", "--sampler", "released-pool"),
    "bus-arrivals": ("bus-arrivals", "--policies", *BUS_PANELS),
    "bus-loads": ("bus-loads", "--policies", *BUS_PANELS),
    "scaling": ("scaling",),
    "transfer": ("transfer",),
    "transfer-20170422": ("transfer", "--sim-version", "2017-04-22"),
    "transfer-corrected": ("transfer", "--corrected"),
    "transfer-pool": ("transfer", "--sim-version", "2017-04-22", "--sampler", "released-pool"),
    "transfer-heuristics": ("transfer-heuristics",),
    "wildfire-behaviour": ("wildfire-behaviour",),
    "wildfire-penalty": ("wildfire-penalty",),
    "wildfire-races": ("wildfire-races",),
    "advantage-estimators": ("advantage-estimators",),
    "advantage-sb3": ("advantage-sb3",),
    "transfer-order": ("transfer-order",),
    "transfer-dt": ("transfer-dt",),
    "transfer-ablation": ("transfer-ablation",),
    "transfer-inputs": ("transfer-inputs",),
    "interval-coverage": ("interval-coverage",),
}
"""Each study by its name (its Make target's), and its command line without the options this
command hands on (:data:`HANDED_ON`), in the order they run: a study comes after those whose
results it reads."""

HANDED_ON = ("--seed", "--results-dir", "--figures-dir", "--runs-dir", "--n-jobs", "--scheduler",
             "--overwrite")
"""This command's options that each study takes as its own, where it has them."""

TIMING = "reproduce_timing.csv"
"""The steps' wall times: each training round, each study's last (finishing) start, the claims."""


@dataclass(frozen=True)
class ReproduceConfig(Validated):
    """Which studies ``reproduce`` runs."""

    studies: tuple[str, ...] = tuple(STUDIES)
    """The studies to run, by name; they run in the order of the default, which is every study."""

    def validate(self) -> None:
        for name in self.studies:
            self.check(name in STUDIES, "studies", "names from " + ", ".join(STUDIES))


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p)
    add_sweep_arguments(p)
    add_config_arguments(p, ReproduceConfig)


def configure(args: argparse.Namespace) -> Command[ReproduceConfig]:
    return Command.of(args, for_scale(ReproduceConfig, args.scale,
                                      **given_fields(args, ReproduceConfig)))


@dataclass(frozen=True)
class Study:
    """One study of a reproduction: its name and its whole command line."""

    name: str
    argv: tuple[str, ...]

    @property
    def trains(self) -> bool:
        """Whether it has training runs (only a study that trains takes ``--runs-dir``)."""
        return "--runs-dir" in self.argv


def study_argv(name: str, cmd: Command[ReproduceConfig], folders: Folders) -> tuple[str, ...]:
    """The command line of study ``name``: its own (:data:`STUDIES`), the scale, and those of
    this command's options that its command has (:data:`HANDED_ON`)."""
    own = STUDIES[name]
    parser = argparse.ArgumentParser()
    cli.command_module(own[0]).add_arguments(parser)
    values = {"--seed": cmd.seed, "--results-dir": folders.results,
              "--figures-dir": folders.figures, "--runs-dir": folders.runs,
              "--n-jobs": cmd.workers.n_jobs, "--scheduler": cmd.workers.scheduler}
    argv = [*own, "--scale", folders.scale]
    for option in HANDED_ON:
        if option not in parser._option_string_actions:
            continue
        if option == "--overwrite":
            argv += ["--overwrite"] if folders.overwrite else []
        elif values[option] is not None:
            argv += [option, str(values[option])]
    return tuple(argv)


def start(study: Study, finish: bool, runs: list) -> int | None:
    """Start ``study`` under a plan (:func:`~repro.studies.kit.sweep.planning`) that lets it run
    to its end (``finish``) or only plans it; the runs it would train join ``runs``. Its exit
    status, or None where it stopped to be started again. A start that only plans writes nothing
    to this command's output, and its refusal (exit status 2, or an exception) is not yet the
    study's: it may wait for another's results, and it runs again in its turn, where an error
    is its own."""
    said = io.StringIO()
    with contextlib.ExitStack() as quiet, planning(finish) as plan:
        if not finish:
            quiet.enter_context(contextlib.redirect_stdout(said))
            quiet.enter_context(contextlib.redirect_stderr(said))
        try:
            status = cli.main(list(study.argv))
        except Planned:
            status = None
        except Exception:
            if finish:
                raise
            status = None
        runs += plan.runs
    return None if not finish and status == 2 else status


def one_round(studies: list[Study], workers: Workers, timing: list[dict]) -> list[Study] | int:
    """Start every study of ``studies`` once and train the runs planned (steps 1 and 2 of the
    module's docstring); the studies not finished, or the exit status of the first study that
    failed. The first study runs until it finishes or plans runs, so every round moves on."""
    runs: list = []
    left: list[Study] = []
    planned: list[str] = []
    for study in studies:
        finish = not left
        if not finish and not study.trains:
            left.append(study)
            continue
        t0, before = time.perf_counter(), len(runs)
        status = start(study, finish, runs)
        if status:
            return status
        if status == 0:
            timing.append(dict(step=study.name, runs=0, wall_seconds=time.perf_counter() - t0))
            continue
        left.append(study)
        planned += [study.name] if len(runs) > before else []
    if runs:
        unique = len({(root, job.name) for job, root in runs})
        print(f"reproduce: training {unique} runs in one pool, for {', '.join(planned)}",
              flush=True)
        t0 = time.perf_counter()
        train_runs(runs, workers)
        timing.append(dict(step="training", runs=unique, wall_seconds=time.perf_counter() - t0))
    return left


def run(cmd: Command[ReproduceConfig], folders: Folders) -> int:
    t0 = time.perf_counter()
    studies = [Study(name, study_argv(name, cmd, folders))
               for name in STUDIES if name in cmd.study.studies]
    timing: list[dict] = []
    while studies:
        studies = one_round(studies, cmd.workers, timing)
        if isinstance(studies, int):
            return studies
    t1 = time.perf_counter()
    status = cli.main(["claims", "--results-dir", str(folders.results)])
    timing.append(dict(step="claims", runs=0, wall_seconds=time.perf_counter() - t1))
    total = time.perf_counter() - t0
    table = pd.DataFrame(timing).round({"wall_seconds": 1})
    prov = provenance(cmd.study, command="reproduce", scale=folders.scale, seed=cmd.seed,
                      wall_seconds=total)
    write_result(folders.open_results() / TIMING, table, prov)
    print(f"reproduce: {len(cmd.study.studies)} studies and their verdicts in {total / 60:.1f} min")
    return status
