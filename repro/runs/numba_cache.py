"""numba's on-disk cache made safe for concurrent processes.

Every compiled kernel of the suite is cached (``njit(cache=True)``), and sweeps compile in several
worker processes at once. numba's cache file allocates the data file of a new signature from the
index it has just read, then writes index and data (numba issue #4807): two processes that compile
two signatures of one function at the same time both take the same data file, and the index ends
up naming one signature's machine code for the other. The next process that loads it crashes
(a wildfire race study, `beyond-races`, segfaulted so after a `make reproduce` whose sweeps had
compiled new engine shapes in two workers). :func:`install` serialises each function's saves, and
lets loads wait for them, with an advisory lock on a file beside its cache.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
from collections.abc import Iterator

from numba.core.caching import IndexDataCacheFile

LOCK_NAME = ".repro-numba-cache.lock"
"""The lock file, one per cache folder."""
NUMBA_SAVE, NUMBA_LOAD = IndexDataCacheFile.save, IndexDataCacheFile.load
"""numba's own save and load, which :func:`install` wraps."""


@contextlib.contextmanager
def locked(cache_file: IndexDataCacheFile, mode: int) -> Iterator[None]:
    """Hold ``mode`` (fcntl.LOCK_EX or LOCK_SH) on the lock file of ``cache_file``'s folder."""
    path = os.path.join(cache_file._cache_path, LOCK_NAME)
    with open(path, "a") as f:
        fcntl.flock(f, mode)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def install() -> None:
    """Wrap numba's cache-file save (exclusive) and load (shared) in the lock; idempotent."""
    if getattr(IndexDataCacheFile.save, "_repro_locked", False):
        return

    def locked_save(self, key, data):
        with locked(self, fcntl.LOCK_EX):
            return NUMBA_SAVE(self, key, data)

    def locked_load(self, key):
        with locked(self, fcntl.LOCK_SH):
            return NUMBA_LOAD(self, key)

    locked_save._repro_locked = True
    IndexDataCacheFile.save, IndexDataCacheFile.load = locked_save, locked_load
