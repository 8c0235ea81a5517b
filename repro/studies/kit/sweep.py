"""Many training runs at once: joblib worker processes by default, an existing Dask cluster when
the user names one (``--scheduler tcp://host:port``).

A sweep is a list of :class:`TrainJob`; each job trains into its own folder under the sweep's root,
named after the job. Runs are checkpointed every epoch by the trainer, so re-running a sweep skips
finished runs and resumes interrupted ones exactly where they stopped. A folder holding a run made
with other settings is refused before anything runs (use another ``--runs-dir``). Each job carries
its own seed in its TrainConfig, so the results do not depend on the scheduler or on the order in
which workers pick up jobs. A study of several sweeps trains them in one pool (:func:`run_sweeps`),
and so do several studies run under one plan (:func:`planning`, as ``reproduce`` runs them).

On a Dask cluster the run folders stay on the client's disk: the client locks a job's folder and
sends its files (none for a new run) with a task that trains one more epoch; the worker trains in a
private temporary folder and sends the files back, the client writes them into place and sends the
next epoch's task. No shared file system is needed, and a worker (or the client) that dies loses at
most the epoch in progress; the next sweep resumes from the client's folders. Each epoch pays for
building the environment and loading the checkpoint on the worker, tens of milliseconds. A cluster
that stops answering mid-sweep (its scheduler lost, or no epoch finished for
:data:`CLUSTER_SILENCE` seconds) ends the sweep in one line naming --scheduler; the same command
run again resumes. So does a worker that dies, joblib's or Dask's, in one line that says so and,
for joblib's, names the signal and its usual cause (SIGKILL: most often memory; SIGSEGV: a crash
in compiled code) (:class:`~repro.core.errors.WorkerDied`).
"""

from __future__ import annotations

import argparse
import asyncio
import dataclasses
import hashlib
import os
import re
import signal
import socket
import tempfile
import threading
import time
import warnings
from contextlib import ExitStack, contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from repro.core.config import add_config_arguments
from repro.core.errors import UsageError, WorkerDied, require
from repro.envs import env_package
from repro.learn.process import configure_process
from repro.learn.run_identity import check_run_folder
from repro.learn.sizes import check_training_size, training_bytes
from repro.runs.files import write_bytes
from repro.runs.kernels import KernelWarning, record as kernel_record
from repro.runs.locks import folder_lock
from repro.runs.provenance import note_trained_under
from repro.runs.run_folder import (CHECKPOINT, CONFIG, KEPT, LOCK, PROGRESS, PROVENANCE,
                                   epochs_done, is_finished, kernels_in_todays_terms, locked_by,
                                   recorded_kernels, writer_lock)
from repro.runs.workers import die_with_parent
from repro.studies.kit.options import (EVERY_CORE, SCHEDULER_FORM, Workers, add_common,
                                     check_scheduler)


@dataclass(frozen=True)
class TrainJob:
    """One training run of a sweep."""

    name: str
    """Unique within the sweep; the run's folder name."""
    train: Any
    """The run's ``repro.learn.config.TrainConfig`` (carries env name, epochs and seed)."""
    env_config: Any
    """The environment package's config dataclass (e.g. ``WildfireConfig``)."""


def policy_stream(seed: int, stream: int, run: str) -> np.random.SeedSequence:
    """The random stream of the trained policy of run ``run`` (its name: the environment's
    settings and the training seed) under child ``stream`` of a study's root ``seed``: keyed by the
    run itself, not by its place among a study's runs, so that a policy scores the same in every
    study and in any subset of a study's runs."""
    digest = hashlib.sha256(run.encode()).digest()
    words = (int.from_bytes(digest[i:i + 4], "little") for i in range(0, 16, 4))
    return np.random.SeedSequence(seed, spawn_key=(stream, *words))


def run_dir(root: Path, job: TrainJob) -> Path:
    return Path(root) / job.name


def is_done(root: Path, job: TrainJob) -> bool:
    """A run is done when it has every epoch the job asks for and its last ``train`` call ended
    (its settings are checked by :func:`run_sweep`)."""
    return is_finished(run_dir(root, job), job.train.epochs)


def _env(job: TrainJob) -> Any:
    return env_package(job.train.env).make_env(job.env_config)


def _train_job(job: TrainJob, folder: Path) -> None:
    """Train (or resume) one job in ``folder``."""
    from repro.learn.trainer import Trainer  # torch: imported where a run trains, not to parse

    Trainer(job.train, _env(job), folder, env_config=job.env_config, param="--runs-dir").train()


def run_job(job: TrainJob, root: Path) -> str:
    """Train (or resume) one job in its folder under ``root``; runs in a joblib worker process."""
    os.environ.setdefault("REPRO_QUIET", "1")  # one progress bar per worker would be noise
    die_with_parent()
    configure_process()
    _train_job(job, run_dir(root, job))
    return job.name


def run_shipped_job(job: TrainJob, files: dict[str, bytes]) -> dict[str, bytes]:
    """Train (or resume) one job on a Dask worker, on nothing but what it was sent: its run
    folder's ``files``. Returns the folder's files after training."""
    os.environ.setdefault("REPRO_QUIET", "1")
    configure_process()
    with tempfile.TemporaryDirectory(prefix="repro-run-") as tmp:
        folder = Path(tmp) / job.name
        folder.mkdir()
        _write_files(folder, files)
        _train_job(job, folder)
        return folder_files(folder)


def folder_files(folder: Path) -> dict[str, bytes]:
    """The files of a run folder by their path in it (kept policies as ``policies/<name>``), in
    the order a resumed run needs them written (the progress rows before the checkpoint, the
    provenance sidecar, which marks a finished call, last)."""
    order = {PROGRESS: 0, CONFIG: 1, CHECKPOINT: 2, PROVENANCE: 4}
    paths = [p for p in (*folder.iterdir(), *(folder / KEPT).glob("*"))
             if p.is_file() and p.name != LOCK]
    names = sorted((p.relative_to(folder).as_posix() for p in paths),
                   key=lambda name: (order.get(name, 3), name))
    return {name: (folder / name).read_bytes() for name in names}


def _write_files(folder: Path, files: dict[str, bytes]) -> None:
    """Write ``folder_files``' output into ``folder`` (atomically, file by file)."""
    for name, data in files.items():
        (folder / name).parent.mkdir(exist_ok=True)
        write_bytes(folder / name, data)


CLUSTER_SILENCE = 30 * 60.0
"""Seconds a Dask sweep waits for the next of its tasks (a training epoch, or a policy's test
episodes) to finish before it takes the cluster for gone (its scheduler or every worker went
away, or the network to them). One such task takes well under a minute at paper scale, so half
an hour without one is silence by a wide margin, also behind workers that start slowly or a
cluster busy with other work; and it is short enough that a sweep left running overnight does
not wait the night for a cluster that is gone."""
_POLL = 0.2
"""Seconds between two looks at a Dask sweep's tasks and its client while none has finished."""


def _cluster_gone(scheduler: str, why: str) -> UsageError:
    return UsageError("--scheduler", f"a Dask cluster that answers until the sweep ends: it "
                      f"stopped answering ({why}); running the same command again resumes from "
                      "the run folders", scheduler)


def _next_finished(done: Any, client: Any, scheduler: str) -> Any:
    """The next task of ``done`` (an ``as_completed``) to finish, waited for at most
    :data:`CLUSTER_SILENCE` seconds; a UsageError naming --scheduler if none finishes in that
    time or the client has lost the scheduler (its tasks are then cancelled)."""
    deadline = time.monotonic() + CLUSTER_SILENCE
    while not done.has_ready():
        if client.status != "running":
            raise _cluster_gone(scheduler, "the client lost the scheduler")
        if time.monotonic() > deadline:
            raise _cluster_gone(scheduler, f"no task finished within {CLUSTER_SILENCE:g} s")
        time.sleep(_POLL)
    future = next(done)
    if future.status == "cancelled":
        raise _cluster_gone(scheduler, "the client lost the scheduler")
    return future


def _died(doing: str, why: str, then: str) -> WorkerDied:
    return WorkerDied(f"a worker process died while {doing} ({why}); {then}")


_RESUMES = ("every finished epoch is kept in the run folders, and the same command resumes "
            "from them")
"""What a sweep whose worker died keeps."""


def _dask_result(future: Any, doing: str, then: str) -> Any:
    """``future``'s result; :class:`WorkerDied` where the workers running it died (Dask retries a
    task on another worker, and gives up once as many as its ``allowed-failures`` died)."""
    from dask.distributed import KilledWorker

    try:
        return future.result()
    except KilledWorker as err:
        worker = getattr(err.last_worker, "address", err.last_worker)
        raise _died(doing, f"Dask: every worker that ran one task died ({err.allowed_failures + 1} "
                    f"of them), the last {worker}; its log says why", then) from None


_SIGNAL_CAUSES = {
    "SIGKILL": "most often the system out of memory (fewer --n-jobs need less), or a kill -9",
    "SIGSEGV": "a crash in compiled code (an invalid memory access, not memory running out; "
               "`make clean` removes numba's compiled kernels, should one be stale)",
    "SIGBUS": "a crash in compiled code, or a file mapped into memory that shrank or a full disk",
    "SIGILL": "compiled code for another CPU (numba's cache from another machine: `make clean`)",
    "SIGFPE": "an arithmetic fault in compiled code",
    "SIGABRT": "a library that aborted (its message is in the worker's output)",
    "SIGTERM": "stopped from outside (kill, or the system shutting down)",
    "SIGINT": "interrupted (Ctrl-C)",
}
"""What the signal that killed a worker usually means, by its name."""


def _exit_causes(message: str) -> str:
    """The exit codes in loky's TerminatedWorkerError ``message`` (``{SIGKILL(-9), EXIT(1)}``),
    each with its usual cause."""
    codes = [int(c) for c in re.findall(r"\((-?\d+)\)", message.split("exit codes", 1)[-1])]
    if not codes:
        return "killed, exit code unknown"
    parts = []
    for code in dict.fromkeys(codes):
        if code >= 0:
            parts.append(f"exit status {code}: the worker exited (its output says why)")
            continue
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        parts.append(f"{name}: {_SIGNAL_CAUSES.get(name, 'a signal from outside')}")
    return "; ".join(parts)


def _on_joblib(fn: Callable[..., Any], tasks: list[tuple], workers: int, doing: str,
               then: str) -> list[Any]:
    """``[fn(*task) for task in tasks]`` on ``workers`` joblib (loky) worker processes;
    :class:`WorkerDied` where one of them dies, naming the signal and what it usually means
    (:func:`_exit_causes`)."""
    from joblib import Parallel, delayed
    from joblib.externals.loky.process_executor import TerminatedWorkerError

    try:
        return Parallel(n_jobs=workers, backend="loky")(delayed(fn)(*task) for task in tasks)
    except TerminatedWorkerError as err:
        raise _died(doing, f"joblib: {_exit_causes(str(err))}", then) from None


def _run_on_dask(pending: list[tuple[TrainJob, Path]], scheduler: str) -> None:
    """Train ``pending``, each a (job, root), on the Dask scheduler ``scheduler``, one epoch per
    task, into their run folders; stops (UsageError naming --scheduler) when the cluster stops
    answering (:func:`_next_finished`), the epochs finished so far kept in the run folders."""
    from dask.distributed import as_completed

    with _dask_client(scheduler) as client, ExitStack() as locks:
        running: dict[Any, tuple[TrainJob, Path]] = {}

        def next_epoch(job: TrainJob, root: Path) -> Any:
            """The task that trains ``job``'s next epoch (or, when its epochs are done, finishes
            its run folder)."""
            folder = run_dir(root, job)
            epochs = min(epochs_done(folder) + 1, job.train.epochs)
            step = dataclasses.replace(job, train=dataclasses.replace(job.train, epochs=epochs))
            future = client.submit(run_shipped_job, step, folder_files(folder), pure=False)
            running[future] = (job, root)
            return future

        for job, root in pending:
            locks.enter_context(writer_lock(run_dir(root, job), "--runs-dir"))
        done = as_completed([next_epoch(job, root) for job, root in pending])
        while not done.is_empty():
            future = _next_finished(done, client, scheduler)
            job, root = running.pop(future)
            folder = run_dir(root, job)
            files = _dask_result(future, f"training {job.name}", _RESUMES)
            for stale in set(folder_files(folder)) - set(files):  # e.g. a killed write's leftovers
                (folder / stale).unlink()
            _write_files(folder, files)
            if not is_finished(folder, job.train.epochs):
                done.add(next_epoch(job, root))


def check_jobs(jobs: list[TrainJob], root: Path) -> None:
    """Refuse (UsageError naming --runs-dir) a sweep whose folders under ``root`` hold runs of
    other settings; checked before anything runs, so that a finished run of other settings is
    neither taken for this sweep's nor left half-overwritten by a sweep that stops at the first
    clash (a driver of several sweeps checks them all first)."""
    names = [j.name for j in jobs]
    if len(set(names)) != len(names):
        raise ValueError("job names must be unique within a sweep")
    for j in jobs:
        check_run_folder(run_dir(root, j), j.train, j.env_config, j.train.env, "--runs-dir")


SWEEP_LOCK = "sweep.lock"
"""Held in a sweep's root folder while it trains: one sweep at a time per folder of runs."""


def run_sweep(jobs: list[TrainJob], root: Path, workers: Workers = EVERY_CORE) -> list[Path]:
    """Run every job that is not done yet; returns every job's folder (in the order given).

    A sweep that has runs to train holds ``root``'s sweep.lock meanwhile: a second sweep over the
    same runs (two identical commands started together) is refused in one line naming
    --runs-dir, as is one that finds a run of its own being trained by another process (a
    ``train`` in it), before any worker starts. The kernels every run was trained under go into
    the command's sidecars (:func:`_note_kernels`). While a plan is made (:func:`planning`), a
    sweep with runs to train trains none: it adds them to the plan and raises :class:`Planned`."""
    return run_sweeps([(jobs, root)], workers)[0]


def run_sweeps(sweeps: list[tuple[list[TrainJob], Path]],
               workers: Workers = EVERY_CORE) -> list[list[Path]]:
    """:func:`run_sweep` of several sweeps, each (jobs, root), at once: every sweep's folders are
    checked before any run trains, and the runs to train, of all of them, train in one pool
    (:func:`train_runs`); each sweep's folders, in the order given."""
    for jobs, root in sweeps:
        check_jobs(jobs, root)
    pending = [(j, Path(root)) for jobs, root in sweeps for j in jobs if not is_done(root, j)]
    plan = _PLAN.get()
    if plan is not None and (pending or not plan.finish):
        plan.runs += pending
        raise Planned(len(pending))
    if pending:
        train_runs(pending, workers)
    done = [[run_dir(root, j) for j in jobs] for jobs, root in sweeps]
    _note_kernels([folder for folders in done for folder in folders])
    return done


class Planned(Exception):
    """A command stopped while a plan was made (:func:`planning`): at a sweep, its runs to train
    added to the plan; to be run again once they are trained."""


@dataclass
class Plan:
    """The runs that commands run under :func:`planning` would train."""

    finish: bool
    """Whether a command may run to its end: a sweep with nothing to train returns its runs and
    the command goes on; else every sweep and task map stops it (:class:`Planned`), before any
    work, so that it is planned, never run."""
    runs: list[tuple[TrainJob, Path]] = dataclasses.field(default_factory=list)
    """(job, root) of each run to train, in the order the sweeps named them."""


_PLAN: ContextVar[Plan | None] = ContextVar("sweep_plan", default=None)
"""The plan being made, if one is (:func:`planning`)."""


@contextmanager
def planning(finish: bool) -> Iterator[Plan]:
    """While it lasts, a sweep trains nothing: :func:`run_sweep` adds the runs it would train to
    the :class:`Plan` this yields and raises :class:`Planned`, and so, unless ``finish``, does a
    sweep with nothing to train and :func:`map_tasks`. So a command run inside it stops at its
    first sweep with runs to train (or, unless ``finish``, at its first sweep or task map), and
    the runs that several commands would train can be trained in one pool
    (:func:`train_runs`)."""
    plan = Plan(finish)
    token = _PLAN.set(plan)
    try:
        yield plan
    finally:
        _PLAN.reset(token)


RECURRENT_COST = 75
"""How many times a recurrent policy's run (``--policy gru``) costs an MLP's of the same epochs
and batch: a bus epoch of 12,000 decisions from 40 workers (about 21,000: each worker keeps the
episode it has in flight) takes the GRU about 2.0 s on one core, the authors' MLP about 0.026 s
(the 2-core AMD EPYC, Zen 5, ``train --env bus --scale paper``). The batch's size in bytes alone
ranks the two alike, which left the pictures' five GRU runs, the longest of any study, to the end
of the pool."""


def longest_first(runs: list[tuple[TrainJob, Path]]) -> list[tuple[TrainJob, Path]]:
    """``runs``, each a (job, root), in the order the workers take them: by their expected cost,
    epochs times the batch's size (:func:`repro.learn.sizes.training_bytes`), times
    :data:`RECURRENT_COST` for a recurrent policy, largest first (ties in the order given), so
    that no worker is left with one long run while the others idle at the end. Each run's result
    does not depend on when it trains."""
    def cost(run: tuple[TrainJob, Path]) -> float:
        train = run[0].train
        weight = RECURRENT_COST if train.policy == "gru" else 1
        return weight * train.epochs * training_bytes(train, _env(run[0]))[0]

    return sorted(runs, key=lambda run: -cost(run))


def _note_kernels(folders: list[Path]) -> None:
    """Note the kernels each run was trained under in the command's sidecars
    (:func:`repro.runs.provenance.note_trained_under`), warning (:class:`KernelWarning`) where this
    process would not train it to the same bits (an earlier arithmetic that trains its policy to
    today's bits does): such results are not regenerated bit for bit on a machine of the pin."""
    now = kernel_record()
    others = 0
    for folder in folders:
        note_trained_under(recorded_kernels(folder, "--runs-dir"))
        others += kernels_in_todays_terms(folder, "--runs-dir") != now
    if others:
        warnings.warn(f"{others} of the {len(folders)} runs were trained under other CPU kernels "
                      "than this process's, or before runs recorded theirs (their sidecars say "
                      "which: trained_under); results from them are regenerated bit for bit only "
                      "under those kernels", KernelWarning, stacklevel=3)


def train_runs(runs: list[tuple[TrainJob, Path]], workers: Workers = EVERY_CORE) -> None:
    """Train (or resume) the runs ``runs``, each a (job, root) of a sweep whose jobs were checked
    (:func:`check_jobs`), in one pool longest first (:func:`longest_first`), whichever sweeps
    they come from; a run named twice (two commands that share it) trains once. Holds each
    root's sweep.lock meanwhile (:func:`run_sweep`)."""
    unique: dict[Path, tuple[TrainJob, Path]] = {}
    for job, root in runs:
        first = unique.setdefault(run_dir(root, job), (job, root))[0]
        if (first.train, first.env_config) != (job.train, job.env_config):
            raise ValueError(f"two sweeps ask for {run_dir(root, job)} with other settings")
    pending = longest_first(list(unique.values()))
    scheduler = workers.scheduler
    processes = min(len(pending), workers.processes)
    if not scheduler:  # the runs train on this machine, ``processes`` at a time
        largest = max((j for j, _ in pending), key=lambda j: sum(training_bytes(j.train, _env(j))))
        check_training_size(largest.train, _env(largest), runs=processes)
    with ExitStack() as locks:
        for root in dict.fromkeys(root for _, root in pending):
            locks.enter_context(folder_lock(root, SWEEP_LOCK, "--runs-dir", "a folder of runs"))
        for job, root in pending:
            holder = locked_by(run_dir(root, job))
            require(holder is None, "--runs-dir", f"a folder of runs no other process is "
                    f"writing to ({holder} holds {job.name}/{LOCK})", str(root))
        if scheduler:
            _run_on_dask(pending, scheduler)
        else:
            _on_joblib(run_job, pending, processes, "training the sweep's runs", _RESUMES)


def map_tasks(fn: Callable[..., Any], tasks: list[tuple],
              workers: Workers = EVERY_CORE) -> list[Any]:
    """``[fn(*task) for task in tasks]`` on joblib worker processes, or on the Dask scheduler
    ``workers`` names; the tasks carry everything they need (no shared disk). On Dask, a cluster
    that stops answering stops the call (:func:`_next_finished`); a worker that dies stops it with
    :class:`~repro.core.errors.WorkerDied`. While a plan that may not finish commands is made
    (:func:`planning`), it raises :class:`Planned` instead."""
    plan = _PLAN.get()
    if plan is not None and not plan.finish:
        raise Planned(0)
    scheduler = workers.scheduler
    if scheduler:
        from dask.distributed import as_completed

        with _dask_client(scheduler) as client:
            futures = [client.submit(fn, *task, pure=False) for task in tasks]
            place = {future.key: i for i, future in enumerate(futures)}
            out: list[Any] = [None] * len(futures)
            done = as_completed(futures)
            for _ in futures:
                future = _next_finished(done, client, scheduler)
                out[place[future.key]] = _dask_result(future, "running its tasks", _RUNS_AGAIN)
            return out
    processes = max(1, min(len(tasks), workers.processes))
    return _on_joblib(fn, tasks, processes, "running its tasks", _RUNS_AGAIN)


_RUNS_AGAIN = ("the same command runs these tasks again, and trains nothing again that its run "
               "folders hold")
"""What :func:`map_tasks` whose worker died keeps (its tasks, policy tests or Monte Carlo cells,
train nothing)."""


SCHEDULER_DEADLINE = 30.0
"""Seconds that finding, reaching and hearing from ``--scheduler`` may take, whatever answers at
the address (a Dask client's own timeout does not cover a listener that never answers)."""
def _within(deadline: float, what: Callable[[], Any]) -> tuple[bool, Any]:
    """(True, what()) if it returns or raises within ``deadline`` seconds (its exception as the
    value), else (False, None). It runs on a daemon thread: one that never returns (a name lookup
    or a read from a listener that never answers) is left behind and ends with the process."""
    out: list[Any] = []

    def call() -> None:
        try:
            out.append(what())
        except BaseException as err:  # handed to the caller as a value
            out.append(err)

    thread = threading.Thread(target=call, daemon=True, name="repro-scheduler-probe")
    thread.start()
    thread.join(deadline)
    return (bool(out), out[0] if out else None)


def _identity(address: str, deadline: float) -> Any:
    """What the Dask server at ``address`` says it is (a dict with ``type``), on an event loop of
    its own."""
    from distributed.comm import connect
    from distributed.security import Security

    async def ask() -> Any:
        comm = await connect(address, timeout=deadline,
                             **Security().get_connection_args("client"))
        try:
            await comm.write({"op": "identity"})
            return await comm.read()
        finally:
            comm.abort()

    loop = asyncio.new_event_loop()
    try:
        return loop.run_until_complete(asyncio.wait_for(ask(), deadline))
    finally:
        loop.close()


def _dask_client(scheduler: str) -> Any:
    """A client of the running Dask scheduler at ``scheduler``. The address's form is checked
    first, then its host is looked up, the server asked what it is, and the client connected,
    each within :data:`SCHEDULER_DEADLINE`; anything else at the address (nothing, a listener that
    never answers, a web server, a Dask worker) is a UsageError naming --scheduler."""
    scheme, host, port = check_scheduler(scheduler)
    from dask.distributed import Client

    deadline = SCHEDULER_DEADLINE
    answered, found = _within(deadline, lambda: socket.getaddrinfo(host, port,
                                                                    type=socket.SOCK_STREAM))
    if not answered or isinstance(found, BaseException) or not found:
        raise UsageError("--scheduler", f"{SCHEDULER_FORM} whose host can be found (within "
                         f"{deadline:g} s)", scheduler)
    ip = found[0][4][0]
    numeric = f"{scheme}://{'[' + ip + ']' if ':' in ip else ip}:{port}"
    answered, identity = _within(deadline, lambda: _identity(numeric, deadline))
    if not answered or not isinstance(identity, dict) or identity.get("type") != "Scheduler":
        what = ("nothing answered within " f"{deadline:g} s" if not answered
                else f"a {identity.get('type')} answered" if isinstance(identity, dict)
                else "no Dask scheduler answered")
        raise UsageError("--scheduler", f"{SCHEDULER_FORM} ({what})", scheduler)
    answered, client = _within(deadline, lambda: Client(scheduler, timeout=deadline))
    if not answered or isinstance(client, BaseException):
        raise UsageError("--scheduler", f"{SCHEDULER_FORM} (it did not take a client within "
                         f"{deadline:g} s)", scheduler)
    return client


def add_sweep_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--runs-dir", default="runs",
                   help="folder of the sweep's run folders (checkpoints; re-running skips "
                        "what is done)")
    p.add_argument("--n-jobs", type=int, help="joblib worker processes (default: all cores)")
    p.add_argument("--scheduler", help="address of an existing Dask scheduler to run on instead")


def add_study_arguments(p: argparse.ArgumentParser, config: type,
                        fields: tuple[str, ...] = ("seeds",)) -> None:
    """The options of a driver that trains a sweep: every driver's (``add_common``), the
    sweep's, and a flag for each of ``fields`` of the study's ``config``."""
    add_common(p)
    add_sweep_arguments(p)
    add_config_arguments(p, config, fields)
