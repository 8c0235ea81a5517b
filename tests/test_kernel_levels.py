"""Training gives the same bytes under every kernel level of an x86-64 CPU with AVX2
(repro.runs.kernels): a short wildfire run of each learner through the real entry point under two
levels, which stand in for two machines.

The levels: torch's scalar kernels (``ATEN_CPU_CAPABILITY=default``) against the AVX2 ones of
torch, its MKL and numpy's OpenBLAS (``ATEN_CPU_CAPABILITY=avx2 MKL_ENABLE_INSTRUCTIONS=AVX2
OPENBLAS_CORETYPE=Haswell``); on an AVX-512 machine each of these changed an unpinned run's bits.
The committed digests that every CI machine checks are tests/test_learner_fingerprint.py's.
"""

from __future__ import annotations

import csv
import io
import subprocess
import sys
from pathlib import Path

import pytest

from repro.learn.trainer import TIMING_COLUMNS
from repro.runs import kernels
from tests.conftest import ROOT, env_without_pins

RUN = ("train", "--env", "wildfire", "--scale", "smoke", "--epochs", "3")
LEARNERS = ("authors", "suite")
LEVELS = {
    "torch scalar": dict(ATEN_CPU_CAPABILITY="default"),
    "AVX2": dict(ATEN_CPU_CAPABILITY="avx2", MKL_ENABLE_INSTRUCTIONS="AVX2",
                 OPENBLAS_CORETYPE="Haswell"),
}


def train(out: Path, learner: str, **env: str) -> Path:
    """Run RUN with ``learner`` into ``out`` in a fresh process."""
    cmd = [sys.executable, "-m", "repro", *RUN, "--learner", learner, "--out", str(out)]
    done = subprocess.run(cmd, env=env_without_pins(REPRO_QUIET="1", **env), cwd=ROOT,
                          capture_output=True, text=True, timeout=240)
    assert done.returncode == 0, done.stderr
    return out


def outputs(folder: Path) -> tuple[str, bytes]:
    """progress.csv without its timing columns (its own text, not re-formatted), and the
    checkpoint's bytes."""
    rows = list(csv.reader(io.StringIO((folder / "progress.csv").read_text())))
    keep = [i for i, name in enumerate(rows[0]) if name not in TIMING_COLUMNS]
    text = "\n".join(",".join(row[i] for i in keep) for row in rows)
    return text, (folder / "checkpoint.pt").read_bytes()


@pytest.mark.slow
@pytest.mark.skipif(not kernels.pinnable(), reason="the pin applies to x86-64 CPUs with AVX2")
@pytest.mark.parametrize("learner", LEARNERS)
def test_kernel_levels_give_the_same_bytes(tmp_path, learner):
    first, second = (outputs(train(tmp_path / str(i), learner, **env))
                     for i, env in enumerate(LEVELS.values()))
    assert first[0] == second[0]  # the progress table
    assert first[1] == second[1]  # the checkpoint
