"""Worker processes that do not outlive the process that started them."""

from __future__ import annotations

import ctypes
import signal
import sys

_PR_SET_PDEATHSIG = 1


def die_with_parent() -> None:
    """Have the kernel end this process (SIGTERM) when its parent dies.

    Called first thing in a sweep's joblib worker: after ``kill -9`` of a driver its loky workers
    would otherwise train on for the rest of their job, writing into run folders that the next run
    of the driver then finds locked. Linux only (elsewhere a no-op).
    """
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
