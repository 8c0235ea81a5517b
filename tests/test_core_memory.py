"""keep_freed_memory: glibc's malloc keeps freed blocks, large ones included; elsewhere a no-op."""

from __future__ import annotations

import platform
import subprocess
import sys

import pytest

from repro.runs.memory import keep_freed_memory

glibc_only = pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="a no-op without glibc")

_FAULTS = """
import ctypes, resource, sys
import numpy as np
from repro.runs.memory import keep_freed_memory
# no transparent huge pages (PR_SET_THP_DISABLE), so that the faults count the 4 KiB pages touched:
# numpy asks for huge pages for large arrays, and whether the kernel has them free varies from
# one allocation to the next
ctypes.CDLL(None).prctl(41, 1, 0, 0, 0)
if sys.argv[1] == "keep":
    keep_freed_memory()
for _ in range(2):
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    block = np.ones(200 << 17)  # 200 MiB, over any mmap threshold
    del block
    print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


def _page_faults(mode: str) -> list[int]:
    """Page faults of allocating, touching and freeing a 200 MiB array, twice, in a new process."""
    out = subprocess.run([sys.executable, "-c", _FAULTS, mode], capture_output=True, text=True,
                         check=True).stdout
    return [int(line) for line in out.split()]


@glibc_only
def test_glibc_accepts_the_settings_and_a_second_call_changes_nothing():
    assert keep_freed_memory() is True
    assert keep_freed_memory() is True


@glibc_only
def test_a_freed_large_block_is_reused_without_page_faults():
    first, again = _page_faults("keep")
    assert again < first / 10
    first, again = _page_faults("default")  # glibc unmaps it: every allocation faults again
    assert again > first / 2
