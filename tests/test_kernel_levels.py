"""Training gives the same bytes on every x86-64 CPU with AVX2 (repro.core.kernels): a short
wildfire run under two kernel levels, and the committed fingerprint of that run, which every CI
machine checks.

The kernel levels stand in for two machines: torch's scalar kernels (``ATEN_CPU_CAPABILITY=
default``) against the AVX2 ones of torch, its MKL and numpy's OpenBLAS (``ATEN_CPU_CAPABILITY=
avx2 MKL_ENABLE_INSTRUCTIONS=AVX2 OPENBLAS_CORETYPE=Haswell``); on an AVX-512 machine each of these
changed an unpinned run's bits. The fingerprints are exact-bit digests of the outputs (progress.csv
without its timing columns, then checkpoint.pt's bytes) computed by this module (``python -m
tests.test_train_fingerprint``) on the code of the commit that added them. They hold for the
versions the suite installs (torch 2.13.0+cpu with its MKL, numpy 2.4, numba, glibc's libm); a new
version of any of them may change a last bit, and then the digests are recomputed, with a line in
CHANGELOG.md. MKL documents its pinned branch for Intel CPUs: on another vendor's CPU a mismatch
says that MKL ran another branch there.
"""

from __future__ import annotations

import csv
import hashlib
import io
import subprocess
import sys
from pathlib import Path

import pytest

from repro.core import kernels
from repro.learn.trainer import TIMING_COLUMNS
from tests.conftest import ROOT, env_without_pins

RUN = ("train", "--env", "wildfire", "--scale", "smoke", "--epochs", "3")
CONFIGS = {  # name: the run's further options
    "default learner": (),
    "one layer, no normalisation, exact FVP": ("--hidden", "32", "--no-obs-norm",
                                               "--fvp-subsample", "1"),
}
LEVELS = {
    "torch scalar": dict(ATEN_CPU_CAPABILITY="default"),
    "AVX2": dict(ATEN_CPU_CAPABILITY="avx2", MKL_ENABLE_INSTRUCTIONS="AVX2",
                 OPENBLAS_CORETYPE="Haswell"),
}
FINGERPRINTS = {
    "default learner": "4f6216b9003aac65063d06d41b1acb17f60321520c33d9ec54007aad4b6fb9c4",
    "one layer, no normalisation, exact FVP":
        "e8d34c86f8feb2afd3c15d323b428db25de82345c40f9a6bc9c3a853e8f96eb5",
}
"""sha256 of each config's outputs, by the ``__main__`` block below."""

needs_pin = pytest.mark.skipif(not kernels.pinnable(),
                               reason="the pin applies to x86-64 CPUs with AVX2")


def train(out: Path, config: str, **env: str) -> Path:
    """Run RUN with the config's options into ``out`` in a fresh process."""
    cmd = [sys.executable, "-m", "repro", *RUN, *CONFIGS[config], "--out", str(out)]
    done = subprocess.run(cmd, env=env_without_pins(REPRO_QUIET="1", **env), cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    return out


def outputs(folder: Path) -> tuple[str, bytes]:
    """progress.csv without its timing columns (its own text, not re-formatted), and the
    checkpoint's bytes."""
    rows = list(csv.reader(io.StringIO((folder / "progress.csv").read_text())))
    keep = [i for i, name in enumerate(rows[0]) if name not in TIMING_COLUMNS]
    text = "\n".join(",".join(row[i] for i in keep) for row in rows)
    return text, (folder / "checkpoint.pt").read_bytes()


def fingerprint(folder: Path) -> str:
    text, checkpoint = outputs(folder)
    return hashlib.sha256(text.encode() + checkpoint).hexdigest()


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[tuple[str, str], Path]:
    root = tmp_path_factory.mktemp("fingerprint")
    return {(c, lv): train(root / f"{i}-{j}", c, **env) for i, c in enumerate(CONFIGS)
            for j, (lv, env) in enumerate(LEVELS.items())}


@pytest.mark.slow
@needs_pin
@pytest.mark.parametrize("config", CONFIGS)
def test_kernel_levels_give_the_same_bytes(runs, config):
    first, second = (outputs(runs[config, level]) for level in LEVELS)
    assert first[0] == second[0]  # the progress table
    assert first[1] == second[1]  # the checkpoint


@pytest.mark.slow
@needs_pin
@pytest.mark.parametrize("config", CONFIGS)
def test_training_reproduces_the_committed_fingerprint(runs, config):
    got = fingerprint(runs[config, "AVX2"])
    assert got == FINGERPRINTS[config], (
        f"{config}: {got}; kernels here {kernels.state()}, CPU flags "
        f"{sorted(f for f in kernels.cpu_flags() if f.startswith(('avx', 'fma')))}")


if __name__ == "__main__":
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        for i, name in enumerate(CONFIGS):
            folder = train(Path(tmp) / str(i), name, **LEVELS["AVX2"])
            print(f'    "{name}": "{fingerprint(folder)}",')
