"""The run folder's promises (repro.runs.run_folder): checkpoints that cannot run code, exact
resume whichever write a kill interrupts (injected, not raced), one writer per folder, one-line
refusals of damaged or foreign folders, and the same bytes for the same run."""

from __future__ import annotations

import json
import os
import random
import shutil
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import pandas as pd
import pytest
import torch

import repro.runs.run_folder as run_folder
import repro.learn.trainer as trainer
from repro.cli import main
from repro.core.errors import UsageError
from repro.envs import toy
from repro.learn.config import train_config
from repro.learn.trained_policy import load_trained_run
from repro.runs.run_folder import TIMING_COLUMNS
from repro.runs import kernels
from repro.runs.files import atomic_path
from repro.runs.run_folder import CHECKPOINT, LOCK, PROGRESS, writer_lock
from repro.studies.kit.options import Workers
from repro.studies.kit.sweep import TrainJob, run_sweep
from tests.conftest import tree_snapshot

TRAIN = ["train", "--env", "toy", "--batch-episodes", "6", "--seed", "3", "--horizon", "10"]


def train(out: Path, epochs: int = 3, *extra: str) -> int:
    return main([*TRAIN, "--epochs", str(epochs), "--out", str(out), *extra])


def files(folder: Path) -> dict[str, bytes]:
    """Every file of a run folder but the measured times: progress.csv without its timing columns,
    and no provenance sidecar (it records wall time)."""
    out = {p.relative_to(folder).as_posix(): p.read_bytes() for p in folder.rglob("*")
           if p.is_file() and p.name not in (PROGRESS, "progress.provenance.json")}
    if (folder / PROGRESS).exists():
        out[PROGRESS] = pd.read_csv(folder / PROGRESS).drop(columns=TIMING_COLUMNS).to_csv()
    return out


@pytest.fixture(scope="module")
def whole(tmp_path_factory) -> Path:
    """An uninterrupted 3-epoch run."""
    out = tmp_path_factory.mktemp("whole") / "run"
    assert train(out) == 0
    return out


# --- safe checkpoints ----------------------------------------------------------------------------

class Payload:
    """Unpickling this creates the file ``marker``: what a crafted checkpoint could do."""

    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def test_a_crafted_checkpoint_is_refused_and_never_runs(tmp_path, whole, capsys):
    marker = tmp_path / "pwned"
    run = tmp_path / "run"
    shutil.copytree(whole, run)
    torch.save({"format": 2, "epoch": 1, "x": Payload(marker)}, run / CHECKPOINT)
    before = tree_snapshot(run)
    capsys.readouterr()
    assert train(run, 4) == 2  # train's resume
    assert main(["bench-bus", "--scale", "smoke", "--checkpoint", str(run / CHECKPOINT),
                 "--results-dir", str(tmp_path / "res")]) == 2
    with pytest.raises(UsageError):
        load_trained_run(run / CHECKPOINT, "toy")
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(CHECKPOINT in line for line in err)
    assert not marker.exists()
    assert tree_snapshot(run) == before
    assert not (tmp_path / "res").exists()


def test_identical_runs_write_identical_checkpoints(tmp_path, whole):
    assert train(tmp_path / "again") == 0
    assert (tmp_path / "again" / CHECKPOINT).read_bytes() == (whole / CHECKPOINT).read_bytes()


# --- exact resume at every kill point ------------------------------------------------------------

class Killed(BaseException):
    """Stands for kill -9: not an Exception, so nothing on the way catches it."""


WRITERS = [(run_folder, "write_json"), (run_folder, "write_text"), (run_folder, "write_bytes"),
           (run_folder, "append_csv")]
"""Every function through which a training run writes its folder (monkeypatched by name): all of
them in run_folder, the trainer writes nothing itself."""


def test_the_trainer_writes_through_the_run_folder_alone():
    writers = {"write_json", "write_text", "write_bytes", "write_csv", "append_csv",
               "save_checkpoint", "append_row"}
    assert not writers & set(vars(trainer))


def kill_at(monkeypatch, when: int, how: str) -> None:
    """Make the ``when``-th write of the run (counted over every writer) die: before it starts,
    half-way (an atomic write leaves its temporary file, an append half a row), or after it."""
    count = [0]

    def wrap(write):
        def killer(dest, data, *args):
            count[0] += 1
            if count[0] - 1 != when:
                return write(dest, data, *args)
            if how == "torn":
                dest = Path(dest)
                if write.__name__ == "append_csv":
                    text = data.to_csv(header=not dest.exists(), index=False)
                    with dest.open("a") as f:
                        f.write(text[:len(text) // 2])
                else:
                    fd, _ = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".tmp" + dest.suffix,
                                             dir=dest.parent)
                    os.write(fd, b"half")
                    os.close(fd)
            elif how == "after":
                write(dest, data, *args)
            raise Killed
        return killer

    for module, name in WRITERS:
        monkeypatch.setattr(module, name, wrap(getattr(module, name)))


WRITES = 1 + 2 * 3 + 1
"""config.json, then a row and a checkpoint per epoch, then the provenance sidecar."""


@pytest.mark.parametrize("how", ["before", "torn", "after"])
@pytest.mark.parametrize("when", range(WRITES))
def test_a_run_killed_at_any_write_resumes_to_the_uninterrupted_files(tmp_path, whole,
                                                                       monkeypatch, when, how):
    run = tmp_path / "run"
    with monkeypatch.context() as m:
        kill_at(m, when, how)
        with pytest.raises(Killed):
            train(run)
    assert train(run) == 0
    assert files(run) == files(whole)


def test_a_progress_table_without_a_checkpoint_starts_again(tmp_path, whole):
    """The window between the first row and the first checkpoint: the row goes."""
    run = tmp_path / "run"
    assert train(run, 1) == 0
    (run / CHECKPOINT).unlink()
    assert train(run) == 0
    assert files(run) == files(whole)


@pytest.mark.parametrize("when", range(0, 2 * WRITES, 3))
def test_a_sweep_killed_at_any_write_resumes_to_the_uninterrupted_runs(tmp_path, monkeypatch,
                                                                        when):
    jobs = [TrainJob(f"seed{s}", train_config("quick", "toy", epochs=3, batch_episodes=6, seed=s),
                     toy.ToyConfig()) for s in (0, 1)]
    run_sweep(jobs, tmp_path / "whole", Workers(n_jobs=1))
    with monkeypatch.context() as m:
        kill_at(m, when, "torn")
        with pytest.raises(Killed):
            run_sweep(jobs, tmp_path / "killed", Workers(n_jobs=1))
    run_sweep(jobs, tmp_path / "killed", Workers(n_jobs=1))
    for job in jobs:
        assert files(tmp_path / "killed" / job.name) == files(tmp_path / "whole" / job.name)


# --- one writer ----------------------------------------------------------------------------------

def test_a_second_writer_is_refused_naming_the_holder(tmp_path, whole, capsys):
    run = tmp_path / "run"
    assert train(run, 2) == 0
    before = files(run)
    capsys.readouterr()
    with writer_lock(run):
        assert train(run) == 2
        assert f"pid {os.getpid()}" in (run / LOCK).read_text()
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"pid {os.getpid()}" in err and LOCK in err
    assert files(run) == before
    assert train(run) == 0 and files(run) == files(whole)


def test_a_lock_left_by_a_killed_process_is_taken_over(tmp_path, whole):
    run = tmp_path / "run"
    code = ("import os, signal, sys; from pathlib import Path; "
            "from repro.runs.run_folder import writer_lock\n"
            "with writer_lock(Path(sys.argv[1])): os.kill(os.getpid(), signal.SIGKILL)")
    res = subprocess.run([sys.executable, "-c", code, str(run)], cwd=Path(__file__).parents[1])
    assert res.returncode == -9 and (run / LOCK).exists()
    assert train(run) == 0
    assert files(run) == files(whole)


# --- damaged or foreign folders ------------------------------------------------------------------

def _truncate(p: Path) -> None:
    p.write_bytes(p.read_bytes()[:len(p.read_bytes()) // 2])


DAMAGE = {
    "truncated checkpoint": (CHECKPOINT, _truncate),
    "random checkpoint": (CHECKPOINT, lambda p: p.write_bytes(random.Random(0).randbytes(3000))),
    "empty checkpoint": (CHECKPOINT, lambda p: p.write_bytes(b"")),
    "checkpoint is a folder": (CHECKPOINT, lambda p: (p.unlink(), p.mkdir())),
    "truncated config": ("config.json", _truncate),
    "truncated kernels record": (run_folder.KERNELS, _truncate),
}


@pytest.mark.parametrize("damage", DAMAGE)
def test_a_damaged_run_folder_is_one_line_and_nothing_changes(tmp_path, capsys, damage):
    run = tmp_path / "run"
    assert train(run, 2) == 0
    name, spoil = DAMAGE[damage]
    spoil(run / name)
    before = {p.name: p.read_bytes() for p in run.iterdir() if p.is_file()}
    capsys.readouterr()
    assert train(run) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--out" in err and name in err
    assert "delete" in err or "repair" in err
    assert {p.name: p.read_bytes() for p in run.iterdir() if p.is_file()} == before


def test_a_checkpoint_of_another_run_is_refused_naming_both_values(tmp_path, capsys):
    assert train(tmp_path / "seed3", 2) == 0
    other = tmp_path / "seed4"
    assert main([*TRAIN[:-4], "--horizon", "10", "--seed", "4", "--epochs", "1",
                 "--out", str(other)]) == 0
    (other / CHECKPOINT).write_bytes((tmp_path / "seed3" / CHECKPOINT).read_bytes())
    capsys.readouterr()
    assert main([*TRAIN[:-4], "--horizon", "10", "--seed", "4", "--epochs", "3",
                 "--out", str(other)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "train.seed: 3 there, 4 here" in err


def test_fewer_epochs_leave_config_json_alone(tmp_path, whole):
    run = tmp_path / "run"
    assert train(run) == 0
    config = (run / "config.json").read_bytes()
    assert train(run, 1) == 0
    assert (run / "config.json").read_bytes() == config


def test_a_corrupt_config_in_a_sweep_is_one_line(tmp_path):
    jobs = [TrainJob("a", train_config("quick", "toy", epochs=1, batch_episodes=6),
                     toy.ToyConfig())]
    run_sweep(jobs, tmp_path)
    _truncate(tmp_path / "a" / "config.json")
    with pytest.raises(UsageError, match="--runs-dir.*config.json"):
        run_sweep(jobs, tmp_path)


# --- one set of kernels --------------------------------------------------------------------------

def test_a_run_records_its_kernels(whole):
    assert run_folder.recorded_kernels(whole) == kernels.record()


def test_the_record_names_the_cpu_where_the_pin_does_not_apply(monkeypatch):
    assert "cpu" not in kernels.record() or not kernels.state()["pinned"]
    monkeypatch.setattr(kernels, "state", lambda: {"pinned": False, "torch": "AVX512"})
    assert set(kernels.record()) == {"pinned", "torch", "cpu"}


def test_resuming_under_other_kernels_is_refused_and_nothing_changes(tmp_path, whole, capsys,
                                                                     monkeypatch):
    run = tmp_path / "run"
    shutil.copytree(whole, run)
    other = {**kernels.record(), "pinned": False, "torch": "AVX512", "cpu": "elsewhere"}
    monkeypatch.setattr(run_folder, "kernel_record", lambda: other)
    before = tree_snapshot(run)
    capsys.readouterr()
    assert train(run, 4) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--out" in err and "kernels.json" in err
    assert "pinned" in err and "AVX512" in err
    assert tree_snapshot(run) == before


def test_a_run_of_the_earlier_arithmetic_is_not_resumed(tmp_path, whole, capsys):
    """A run trained under torch and MKL's AVX2 branch (its kernels.json names no arithmetic)
    would continue with other bits: refused, naming the arithmetic."""
    run = tmp_path / "run"
    shutil.copytree(whole, run)
    earlier = {k: v for k, v in kernels.record().items() if k != "arithmetic"}
    (run / run_folder.KERNELS).write_text(json.dumps({**earlier, "mkl": "AVX2"}))
    before = tree_snapshot(run)
    capsys.readouterr()
    assert train(run, 4) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"arithmetic None -> {kernels.ARITHMETIC}" in err
    assert tree_snapshot(run) == before


@pytest.mark.parametrize("policy, refused", [("mlp", False), ("gru", True)])
def test_an_earlier_arithmetic_of_the_same_bits_resumes(tmp_path, whole, policy, refused):
    """A run recorded under arithmetic 1 resumes where that arithmetic trains its policy to
    today's bits (the mlp), and is refused where it does not (the gru, then in torch)."""
    run = tmp_path / "run"
    shutil.copytree(whole, run)
    (earlier,) = (a for a, policies in kernels.SAME_BITS.items() if "mlp" in policies)
    (run / run_folder.KERNELS).write_text(json.dumps({**kernels.record(), "arithmetic": earlier}))
    config = json.loads((run / "config.json").read_text())
    config["train"]["policy"] = policy  # read by the kernel check only, before any training
    (run / "config.json").write_text(json.dumps(config))
    if refused:
        with pytest.raises(UsageError, match=f"arithmetic {earlier} -> {kernels.ARITHMETIC}"):
            run_folder.check_kernels(run)
    else:
        run_folder.check_kernels(run)


def test_a_run_from_before_the_record_is_taken_at_its_provenance(tmp_path, whole, monkeypatch):
    """A finished run without kernels.json is checked against its sidecar's kernels (and refused
    where they differ); one whose sidecar has none resumes with a warning."""
    run = tmp_path / "run"
    shutil.copytree(whole, run)
    (run / run_folder.KERNELS).unlink()
    assert run_folder.recorded_kernels(run) == kernels.record()
    with monkeypatch.context() as patch:
        patch.setattr(run_folder, "kernel_record", lambda: {"pinned": False, "cpu": "elsewhere"})
        assert train(run, 4) == 2
    side = run / run_folder.PROVENANCE
    side.write_text(side.read_text().replace('"kernels"', '"kernels_unrecorded"'))
    assert run_folder.recorded_kernels(run) is None
    with pytest.warns(kernels.KernelWarning, match="not recorded"):
        assert train(run, 4) == 0
    assert pd.read_csv(run / PROGRESS).shape[0] == 4


def test_a_sweeps_sidecars_name_the_kernels_its_runs_were_trained_under(tmp_path):
    """Every run's kernels go into the command's sidecars (``trained_under``), with a warning
    where some are not this process's, until the command ends."""
    from repro.runs.provenance import provenance
    from repro.runs.results import release_results

    jobs = [TrainJob(name, train_config("quick", "toy", epochs=1, batch_episodes=6, seed=seed),
                     toy.ToyConfig()) for seed, name in enumerate("ab")]
    try:
        run_sweep(jobs, tmp_path)
        assert provenance({}, command="x", scale=None, seed=None, wall_seconds=0)[
            "trained_under"] == [kernels.record()]
        other = {**kernels.record(), "pinned": False, "cpu": "elsewhere"}
        (tmp_path / "b" / run_folder.KERNELS).write_text(json.dumps(other))
        with pytest.warns(kernels.KernelWarning, match="1 of the 2 runs"):
            run_sweep(jobs, tmp_path)
        recorded = provenance({}, command="x", scale=None, seed=None, wall_seconds=0)
        assert sorted(json.dumps(k, sort_keys=True) for k in recorded["trained_under"]) == sorted(
            json.dumps(k, sort_keys=True) for k in (kernels.record(), other))
        # an earlier arithmetic that trains the run's policy (mlp) to today's bits: recorded as
        # it was, no warning
        [(earlier, _)] = kernels.SAME_BITS.items()
        same = {**kernels.record(), "arithmetic": earlier}
        (tmp_path / "b" / run_folder.KERNELS).write_text(json.dumps(same))
        release_results()
        with warnings.catch_warnings():
            warnings.simplefilter("error", kernels.KernelWarning)
            run_sweep(jobs, tmp_path)
        assert same in provenance({}, command="x", scale=None, seed=None,
                                  wall_seconds=0)["trained_under"]
    finally:
        release_results()
    assert "trained_under" not in provenance({}, command="x", scale=None, seed=None,
                                             wall_seconds=0)


def test_a_loaded_policy_names_the_kernels_of_its_run(whole):
    """A checkpoint (or kept policy) of a run folder, loaded to act, puts its run's kernels into
    the command's sidecars."""
    from repro.runs.provenance import provenance
    from repro.runs.results import release_results

    for path in (whole / CHECKPOINT, sorted((whole / run_folder.KEPT).iterdir())[-1]):
        try:
            load_trained_run(path, "toy")
            assert provenance({}, command="x", scale=None, seed=None, wall_seconds=0)[
                "trained_under"] == [kernels.record()]
        finally:
            release_results()


def test_atomic_path_leaves_nothing_on_failure(tmp_path):
    with pytest.raises(RuntimeError), atomic_path(tmp_path / "x.csv"):
        raise RuntimeError
    assert list(tmp_path.iterdir()) == []
