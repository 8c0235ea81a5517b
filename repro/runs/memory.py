"""Memory: what the machine has (:func:`available_memory`, :func:`require_memory`, for up-front
checks of sizes), and keeping freed memory in the process.

Keep freed memory in the process (glibc's malloc), so large temporaries do not cost page faults.

By default glibc hands every freed block above 128 KiB (then, adaptively, somewhat more) back to the
kernel, and the next allocation of that size takes a page fault on first touch of each 4 KiB page.
A training epoch allocates and frees many arrays of a few MiB (a 32-unit layer over 30,000
decisions is 3.8 MiB); on the 2-core VMs this suite is developed on, a fault costs about 5 us, so a
3.8 MiB temporary cost about 5 ms to allocate and the forward pass of the policy took 23 ms of CPU
instead of 6 (`bench-learn` measures the epoch). Raising the mmap and trim thresholds makes
malloc reuse freed blocks instead: the process keeps its peak heap rather than returning it, and a
training process's peak is that of its largest epoch.

Blocks over the largest mmap threshold (32 MiB) were still mapped afresh every time, and epochs of
long-trained wildfire policies (up to millions of decisions) are made of such blocks: on one
epoch of 1.97 million decisions the TRPO step took 20.7 s with 2.0 million page faults, and 11.8 s
with 0.34 million once malloc was told to map none (M_MMAP_MAX = 0), so that large blocks come
from the heap and are reused too (two other training processes shared the machine meanwhile).
If the heap cannot grow, malloc still maps memory (glibc's sysmalloc ignores the mmap limits for
that fallback).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

from repro.core.errors import UsageError

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD, _M_MMAP_MAX = -1, -3, -4  # from glibc's malloc.h
_KEEP = 1 << 30  # bytes of free memory at the top of the heap that malloc keeps
_MMAP = 32 << 20  # blocks below this come from the heap: glibc's largest mmap threshold on 64-bit


def keep_freed_memory() -> bool:
    """Ask glibc's malloc to keep freed memory for reuse; True if it did, False where the C
    library is not glibc (a no-op there). Idempotent, per process."""
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError, TypeError):
        return False
    return (bool(mallopt(_M_MMAP_THRESHOLD, _MMAP)) and bool(mallopt(_M_MMAP_MAX, 0))
            and bool(mallopt(_M_TRIM_THRESHOLD, _KEEP)))


def available_memory() -> int | None:
    """Bytes this process can expect to allocate now: the kernel's estimate of available memory
    (Linux's MemAvailable), or less where a control group caps the process; else the machine's
    physical memory; None where neither is known."""
    found = []
    try:
        with open("/proc/meminfo") as f:
            found += [int(line.split()[1]) * 1024 for line in f
                      if line.startswith("MemAvailable:")]
    except (OSError, ValueError, IndexError):
        pass
    try:
        with open("/sys/fs/cgroup/memory.max") as f:
            cap = f.read().strip()
        with open("/sys/fs/cgroup/memory.current") as f:
            found.append(int(cap) - int(f.read().strip()))
    except (OSError, ValueError):  # no cgroup v2 cap ("max" is none)
        pass
    if not found:
        try:
            found.append(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
        except (ValueError, OSError, AttributeError):
            return None
    return max(min(found), 0)


def require_memory(need: float, param: str, got: object, what: str) -> None:
    """Refuse (UsageError naming ``param``) a size whose ``what`` ("a training epoch") needs at
    least ``need`` bytes when the machine has fewer available: an up-front check, so that a size
    that cannot fit is one line rather than a MemoryError (or the kernel's kill) minutes in.
    Estimates are lower bounds, so a size that fits is never refused."""
    have = available_memory()
    if have is not None and need > have:
        raise UsageError(param, f"a size that fits in this machine's memory ({what}: at least "
                         f"{_gib(need)} needed, {_gib(have)} available now)", got)


def _gib(n: float) -> str:
    return f"{n / 2**30:,.1f} GiB"
