"""The CPU kernels pinned when repro is imported (repro.runs.kernels): what is set, what is left
alone, and that the pin takes in the processes the suite starts."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from repro.runs import kernels
from tests.conftest import ROOT, env_without_pins

pytestmark = pytest.mark.slow  # studies end to end, subprocesses: left out of make test-fast

PINNABLE = kernels.pinnable()
needs_pin = pytest.mark.skipif(not PINNABLE, reason="the pin applies to x86-64 CPUs with AVX2")
SET_BY_PIN = (*kernels.TORCH_PINS, *kernels.NUMPY_VARIABLES)


def python(code: str, **env: str) -> str:
    """stdout of ``python -c code`` in a fresh process."""
    out = subprocess.run([sys.executable, "-c", code], env=env_without_pins(**env), cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout


REPORT = ("import json, os, repro; from repro.runs import kernels; "
          "print(json.dumps({'env': {k: os.environ.get(k) for k in %r}, "
          "'state': kernels.state(), 'problems': kernels.problems()}))")


def report(prelude: str = "", **env: str) -> dict:
    names = [*SET_BY_PIN, *kernels.MKL_OVERRIDES, "OPENBLAS_CORETYPE", "OPENBLAS_L2_SIZE"]
    return json.loads(python(prelude + REPORT % names, **env).splitlines()[-1])


@needs_pin
def test_this_process_runs_the_pinned_kernels():
    """conftest imports repro first, so the tests themselves compute with the pinned kernels."""
    state = kernels.state()
    assert kernels.problems() == []
    assert state["pinned"] and state["torch"] == "AVX2" and state["mkl"] in ("COMPATIBLE", None)
    assert state["numpy"] in ("X86_V3", "other")
    assert state["arithmetic"] == kernels.ARITHMETIC


@needs_pin
def test_import_pins_torch_and_mkl_over_what_the_environment_says():
    """MKL's COMPATIBLE branch is the one it honours on every vendor's CPU (on AMD it ran AUTO
    under MKL_CBWR=AVX2); an instruction level named in the environment would override it."""
    r = report("import os; ", ATEN_CPU_CAPABILITY="default", MKL_ENABLE_INSTRUCTIONS="AVX512",
               MKL_CBWR="AUTO")
    assert r["env"]["ATEN_CPU_CAPABILITY"] == "avx2"
    assert r["env"]["MKL_CBWR"] == "COMPATIBLE" and r["env"]["MKL_ENABLE_INSTRUCTIONS"] is None
    assert r["state"]["torch"] == "AVX2" and r["state"]["mkl"] in ("COMPATIBLE", None)
    assert r["problems"] == []


@needs_pin
def test_openblas_settings_are_never_touched():
    """Machines set these against crashes and wrong results of older OpenBLAS builds."""
    assert report()["env"]["OPENBLAS_CORETYPE"] == os.environ.get("OPENBLAS_CORETYPE")
    r = report(OPENBLAS_CORETYPE="Haswell", OPENBLAS_L2_SIZE="262144")
    assert (r["env"]["OPENBLAS_CORETYPE"], r["env"]["OPENBLAS_L2_SIZE"]) == ("Haswell", "262144")


@needs_pin
def test_numpys_own_settings_are_left_alone():
    r = report(NPY_ENABLE_CPU_FEATURES="X86_V3")
    assert r["env"]["NPY_ENABLE_CPU_FEATURES"] == "X86_V3"
    assert r["env"]["NPY_DISABLE_CPU_FEATURES"] is None


def test_opt_out_leaves_everything_alone():
    r = report(REPRO_NATIVE_KERNELS="1", ATEN_CPU_CAPABILITY="default")
    assert r["env"]["ATEN_CPU_CAPABILITY"] == "default"
    assert r["env"]["MKL_CBWR"] is None and r["env"]["NPY_DISABLE_CPU_FEATURES"] is None
    assert r["state"]["pinned"] is False and r["problems"] == []


@needs_pin
def test_a_pin_that_came_too_late_is_reported():
    """torch computed before repro was imported: its kernels are chosen and the pin cannot take."""
    r = report("import numpy, torch; torch.ones(8, 8) @ torch.ones(8, 8); ",
               ATEN_CPU_CAPABILITY="default")
    assert r["state"]["torch"] == "DEFAULT"
    assert any("torch runs its DEFAULT kernels" in p for p in r["problems"])
    assert r["env"]["NPY_DISABLE_CPU_FEATURES"] is None  # numpy came first: not set, not claimed


def test_the_pin_needs_avx2_and_fma(monkeypatch):
    monkeypatch.delenv(kernels.OPT_OUT, raising=False)
    monkeypatch.setattr(kernels.platform, "machine", lambda: "x86_64")
    assert kernels.pinnable({"avx", "avx2", "fma"})
    assert not kernels.pinnable({"avx", "fma"})
    assert not kernels.pinnable({"avx2"})
    monkeypatch.setattr(kernels.platform, "machine", lambda: "arm64")
    assert not kernels.pinnable({"avx2", "fma"})


def test_provenance_records_the_kernels():
    import torch  # noqa: F401  (machine() reports the kernels where torch is loaded)

    from repro.runs.provenance import machine

    assert machine()["kernels"] == kernels.state()


def test_a_machine_the_pin_does_not_apply_to_is_told_so(monkeypatch):
    """One accurate line, and only where the user did not opt out."""
    monkeypatch.setattr(kernels, "pinnable", lambda flags=None: False)
    monkeypatch.delenv(kernels.OPT_OUT, raising=False)
    with pytest.warns(kernels.KernelWarning, match="not an x86-64 CPU with AVX2 and FMA"):
        assert len(kernels.check()) == 1
    monkeypatch.setenv(kernels.OPT_OUT, "1")
    assert kernels.check() == []

