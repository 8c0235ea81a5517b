"""The arithmetic of training, made the same bits on every x86-64 CPU with AVX2 and FMA, Intel or
AMD, by construction.

Libraries pick their vectorised kernels by what the CPU supports, and kernels of different widths
sum in different orders; MKL (torch's BLAS and LAPACK) also picks them by the CPU's vendor: its
reproducibility branches (``MKL_CBWR=AVX2``) hold on Intel CPUs only, and on AMD it ran its own
choice, so a run gave other bits there. So the learner keeps every vendor-dependent library out of
its arithmetic:

- the policy network's forward pass and derivative products, the TRPO step's sums, the linear
  baseline's normal equations and solve, and the orthogonal initialisation are compiled loops
  (:mod:`repro.learn.network`, :mod:`repro.learn.trpo`, :mod:`repro.learn.baseline`,
  :mod:`repro.learn.policy`). Without fast-math, LLVM neither reorders their sums nor fuses their
  multiply-adds, so they give the same bits whatever CPU they are compiled for (a run compiled for
  ``NUMBA_CPU_NAME=generic``, ``haswell`` and the AVX-512 hosts gave the same bytes);
- libm's exp, log and tanh, which they call, choose one code path on every CPU with FMA;
- torch keeps the parameters, draws the initial weights from its generator and saves checkpoints.

:func:`pin`, run when ``repro`` is imported and so before torch or numpy compute anything, pins
what still depends on the CPU around that arithmetic:

- ``ATEN_CPU_CAPABILITY=avx2``: torch's own kernels (its vectorised normal draws) at AVX2;
- ``MKL_CBWR=COMPATIBLE``: MKL's cross-vendor branch, the one branch it documents as giving the
  same results on Intel and other vendors' CPUs, for what still runs in torch's MKL outside the
  learner's arithmetic (the optional "mlp" baseline's fit, a user's own torch code);
- ``NPY_DISABLE_CPU_FEATURES``: numpy's ufuncs at X86_V3 (AVX2) on an AVX-512 machine, unless the
  environment says which numpy features to use itself.

torch and MKL read their variables when they first compute, numpy when it is imported: torch may be
imported before ``repro`` as long as it has run no operation, numpy may not. torch's and MKL's
variables are overridden where set; numpy's are left alone where the environment sets either of
them. numpy's BLAS is never used in training, and its variables are never touched (some machines
set ``OPENBLAS_CORETYPE`` and ``OPENBLAS_L2_SIZE`` because older OpenBLAS builds compute wrong
results or crash on their processors).

:data:`ARITHMETIC` names this construction; a run folder records it with the kernels, so a run is
never resumed under another. ``REPRO_NATIVE_KERNELS=1`` leaves every variable as it is.
:func:`state` says which kernels are in use, and :func:`check` warns, in one accurate line per
cause, where the pin did not take. This module imports only the standard library at its top, so
that it runs before numpy.
"""

from __future__ import annotations

import functools
import os
import platform
import sys
import warnings
from typing import Any

OPT_OUT = "REPRO_NATIVE_KERNELS"
"""Set to 1 to run every library's own choice of kernels for this CPU."""
ARITHMETIC = "compiled-fixed-order-2"
"""The learner's arithmetic: its version changes whenever a change to the code changes the bits
of training (the earliest, torch and MKL's AVX2 branch, is recorded as runs without it). 1: the
mlp policy in compiled loops, the gru in torch and MKL's COMPATIBLE branch; 2: the gru in
compiled loops too."""
SAME_BITS = {"compiled-fixed-order-1": ("mlp",)}
"""Earlier arithmetics that train the policies named (``TrainConfig.policy``) to the same bits as
:data:`ARITHMETIC`: a run of such a policy recorded under one resumes under today's."""
TORCH_PINS = {"ATEN_CPU_CAPABILITY": "avx2", "MKL_CBWR": "COMPATIBLE"}
"""torch's kernel level and its MKL's code branch."""
MKL_OVERRIDES = ("MKL_ENABLE_INSTRUCTIONS",)
"""Removed by the pin: where it names an instruction level MKL runs that level's kernels whatever
MKL_CBWR says."""
NUMPY_ABOVE_AVX2 = "X86_V4 AVX512_ICL AVX512_SPR"
"""numpy's dispatch targets above X86_V3 (numpy 2.4 on x86-64), switched off on AVX-512 CPUs."""
NUMPY_VARIABLES = ("NPY_DISABLE_CPU_FEATURES", "NPY_ENABLE_CPU_FEATURES")
MKL_BRANCHES = {0: "off", 1: "off", 2: "AUTO", 3: "COMPATIBLE", 4: "SSE2", 6: "SSSE3", 7: "SSE4_1",
                8: "SSE4_2", 9: "AVX", 10: "AVX2", 11: "AVX512_MIC", 12: "AVX512",
                13: "AVX512_MIC_E1", 14: "AVX512_E1"}
"""mkl_cbwr_get(MKL_CBWR_BRANCH) values (mkl_service.h) by name."""


def cpu_flags() -> set[str]:
    """The CPU's feature flags as Linux lists them (empty where /proc/cpuinfo is not readable)."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def pinnable(flags: set[str] | None = None) -> bool:
    """Whether this machine takes the pin: x86-64 with AVX2 and FMA, and no opt-out."""
    if os.environ.get(OPT_OUT, "") not in ("", "0"):
        return False
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return False
    return {"avx2", "fma"} <= (cpu_flags() if flags is None else flags)


def pin() -> bool:
    """Set the variables of the module docstring (where :func:`pinnable`); True if it did."""
    flags = cpu_flags()
    if not pinnable(flags):
        return False
    os.environ.update(TORCH_PINS)
    for name in MKL_OVERRIDES:
        os.environ.pop(name, None)
    if ("avx512f" in flags and "numpy" not in sys.modules
            and not any(v in os.environ for v in NUMPY_VARIABLES)):
        os.environ["NPY_DISABLE_CPU_FEATURES"] = NUMPY_ABOVE_AVX2
    return True


def mkl_branch() -> str | None:
    """The code branch torch's MKL runs (``COMPATIBLE`` when pinned, ``off`` or ``AUTO`` when MKL
    picks by CPU), or None where torch has no MKL whose settings can be read. Imports torch."""
    import ctypes

    import torch

    if not torch.backends.mkl.is_available():
        return None
    try:
        lib = ctypes.CDLL(os.path.join(os.path.dirname(torch.__file__), "lib", "libtorch_cpu.so"))
        get = lib.mkl_serv_cbwr_get
    except (OSError, AttributeError):
        return None
    get.restype, get.argtypes = ctypes.c_int, [ctypes.c_int]
    value = get(1)  # MKL_CBWR_BRANCH
    return MKL_BRANCHES.get(value, str(value))


def numpy_level() -> str:
    """The highest numpy dispatch target in use on x86-64 (X86_V3 is AVX2), or 'other'."""
    from numpy._core._multiarray_umath import __cpu_features__ as features

    for target in ("AVX512_SPR", "AVX512_ICL", "X86_V4", "X86_V3"):
        if features.get(target):
            return target
    return "other"


@functools.lru_cache(maxsize=1)
def state() -> dict[str, Any]:
    """Which arithmetic and kernels are in use: the learner's arithmetic, whether the pin applies
    here, torch's level, MKL's branch, numpy's level (fixed once the libraries have computed, so
    computed once). Imports torch and numpy."""
    import torch

    return {"arithmetic": ARITHMETIC, "pinned": pinnable(),
            "torch": torch.backends.cpu.get_cpu_capability(), "mkl": mkl_branch(),
            "numpy": numpy_level()}


def record() -> dict[str, Any]:
    """What decides the bits of training here (:func:`describe` of this process and CPU): a run
    folder keeps it, so that a resumed run is not continued under other kernels. Imports torch
    and numpy."""
    from repro.runs.cpu import cpu_model

    return describe(state(), cpu_model())


def describe(now: dict[str, Any], cpu: str) -> dict[str, Any]:
    """The kernel state ``now`` and, where the pin does not apply, the ``cpu``, whose own kernels
    then sum in their own order."""
    return dict(now) if now.get("pinned") else {**now, "cpu": cpu}


def problems(now: dict[str, Any] | None = None) -> list[str]:
    """What differs from the pin where it applies (nothing where it does not)."""
    now = state() if now is None else now
    if not now["pinned"]:
        return []
    found = []
    if now["torch"] != "AVX2":
        found.append(f"torch runs its {now['torch']} kernels, not AVX2 (it computed before "
                     "repro was imported, which sets ATEN_CPU_CAPABILITY)")
    if now["mkl"] not in (None, "COMPATIBLE"):
        found.append(f"torch's MKL runs its {now['mkl']} branch, not COMPATIBLE (it computed "
                     "before repro was imported, which sets MKL_CBWR); only the mlp baseline's "
                     "fit uses it")
    if now["numpy"] not in ("X86_V3", "other"):
        found.append(f"numpy runs its {now['numpy']} ufunc loops, not X86_V3 (it was imported "
                     "before repro, which sets NPY_DISABLE_CPU_FEATURES)")
    return found


class KernelWarning(RuntimeWarning):
    """The kernels are not the pinned ones: results may differ from other machines' in the last
    bits."""


def check() -> list[str]:
    """Warn (:class:`KernelWarning`, once per process and problem) where the pin did not take, or
    does not apply on this machine (not opted out of); returns the problems."""
    found = problems()
    if not pinnable() and os.environ.get(OPT_OUT, "") in ("", "0"):
        found.append(f"this machine ({platform.machine()}) is not an x86-64 CPU with AVX2 and "
                     "FMA, the CPUs the learner's arithmetic is the same bytes on (its run "
                     "folders record the CPU)")
    for problem in found:
        warnings.warn(f"{problem}; training results may differ in the last bits from those of "
                      "other machines", KernelWarning, stacklevel=2)
    return found
