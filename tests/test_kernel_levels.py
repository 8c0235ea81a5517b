"""Training gives the same bytes whatever kernels the CPU would choose (repro.runs.kernels): a
short wildfire run of each learner through the real entry point on two set-ups that stand in for
two machines of different vendors and instruction sets.

- pinned: the pin, and numba compiling for this CPU (on the project's machines, AVX-512);
- elsewhere: no pin at all (``REPRO_NATIVE_KERNELS=1``: torch's and numpy's widest kernels, MKL's
  own choice of branch) and numba compiling for a generic x86-64 (``NUMBA_CPU_NAME=generic``: SSE2,
  no FMA). numba keys each cached kernel by the CPU it was compiled for as well as its signature,
  so these kernels sit in the suite's cache beside this CPU's, neither loaded for the other: the
  first test run after a change to the kernels' source compiles them, later runs load them.

The learner's arithmetic uses neither torch's nor MKL's kernels, and its compiled loops fix the
order of their sums, so the two agree. The committed digests that every CI machine checks are
tests/test_learner_fingerprint.py's.
"""

from __future__ import annotations

import csv
import io
import subprocess
import sys
from pathlib import Path

import pytest

from repro.runs.run_folder import TIMING_COLUMNS
from repro.runs import kernels
from tests.conftest import ROOT, env_without_pins

RUN = ("train", "--env", "wildfire", "--scale", "smoke", "--epochs", "3")
LEARNERS = ("authors", "suite")
LEVELS = {
    "pinned": dict(),
    "elsewhere": dict(REPRO_NATIVE_KERNELS="1", NUMBA_CPU_NAME="generic"),
}
"""Environment of each set-up."""


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
@pytest.mark.timeout(900)  # four training processes, the generic kernels compiled on a first run
@pytest.mark.skipif(not kernels.pinnable(), reason="the pin applies to x86-64 CPUs with AVX2")
def test_kernel_levels_give_the_same_bytes(tmp_path):
    """Both learners in one test, so that the generic set-up's shared kernels compile once."""
    for learner in LEARNERS:
        first, second = (outputs(train(tmp_path / f"{learner}-{name}", learner, **env))
                         for name, env in LEVELS.items())
        assert first[0] == second[0], learner  # the progress table
        assert first[1] == second[1], learner  # the checkpoint
