"""numba's on-disk cache made safe for concurrent processes.

Every compiled kernel of the suite is cached (``njit(cache=True)``), and sweeps compile in several
worker processes at once. numba's cache file allocates the data file of a new signature from the
index it has just read, then writes index and data (numba issue #4807): two processes that compile
two signatures of one function at the same time both take the same data file, and the index ends
up naming one signature's machine code for the other. The next process that loads it crashes
(a wildfire race study, `beyond-races`, segfaulted so after a `make reproduce` whose sweeps had
compiled new engine shapes in two workers). :func:`install` serialises each function's saves, and
lets loads wait for them, with an advisory lock on a file beside its cache.

A compiled function's machine-code symbol is its name, its argument types and numba's id of the
compilation, a counter that starts at 1 in every process; a record type enters the name as
another per-process counter. Two processes that compile a kernel for two shapes (the wildfire
engine for N = 3 and for N = 6) in the same order thus give both compilations one symbol, and a
third process that loads both from the cache binds the second to the first one's code (LLVM keeps
one definition of a symbol): the engine of one shape ran on the other's states and crashed in
``_setup`` (SIGSEGV). The cache keys (signature and bytecode) were right; the symbols were not
unique. :func:`install` also makes numba's compilation ids random (:class:`RandomIds`), so that no
two compilations of any processes share a symbol.

numba keys a cached function on its own file only (its modification time and size): a kernel
that calls a kernel of another module keeps the callee's old code compiled into it after the
callee's source changes, until the cache is cleared. :func:`install` adds a digest of the source
a kernel can see (:func:`source_digest`: the layers of the package up to the learner) to every
cache file's stamp, so that any change there makes every cached kernel recompile once rather
than run stale code, and a change above (a study, a claim) recompiles nothing.
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import hashlib
import os
import secrets
from collections.abc import Iterator
from pathlib import Path

from numba.core.bytecode import FunctionIdentity
from numba.core.caching import IndexDataCacheFile

LOCK_NAME = ".repro-numba-cache.lock"
"""The lock file, one per cache folder."""
NUMBA_SAVE, NUMBA_LOAD = IndexDataCacheFile.save, IndexDataCacheFile.load
NUMBA_INIT = IndexDataCacheFile.__init__
"""numba's own save, load and cache-file set-up, which :func:`install` wraps."""
PACKAGE = Path(__file__).resolve().parents[1]
"""The suite's package folder, whose source :func:`source_digest` hashes."""
KERNEL_SOURCES = ("__init__.py", "paper.py", "core", "envs", "runs", "learn")
"""The parts of the package a compiled kernel can see: the kernels live in ``core``, ``envs`` and
``learn``, which import only from their own layers and those below (tests/test_layering.py). A
change to the studies, the claims or the command line leaves the cached kernels valid."""


@functools.cache
def source_digest(root: Path = PACKAGE) -> str:
    """SHA-256 of every ``.py`` file of :data:`KERNEL_SOURCES` under ``root`` (relative names and
    contents, sorted)."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        name = path.relative_to(root)
        if name.parts[0] in KERNEL_SOURCES:
            digest.update(str(name).encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


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


class RandomIds:
    """numba's compilation ids (``FunctionIdentity._unique_ids``, an iterator) drawn at random,
    96 bits from the operating system each: unique across processes (forked workers too, which
    would copy a counter or a seeded generator); two of a million compilations share one with a
    probability below 1e-17."""

    BITS = 96

    def __iter__(self) -> RandomIds:
        return self

    def __next__(self) -> int:
        return secrets.randbits(self.BITS)


def install() -> None:
    """Wrap numba's cache-file save (exclusive) and load (shared) in the lock, stamp every cache
    file with the package's :func:`source_digest` too, and draw numba's compilation ids at random
    (:class:`RandomIds`); idempotent."""
    if getattr(IndexDataCacheFile.save, "_repro_locked", False):
        return
    FunctionIdentity._unique_ids = RandomIds()

    def locked_save(self, key, data):
        with locked(self, fcntl.LOCK_EX):
            return NUMBA_SAVE(self, key, data)

    def locked_load(self, key):
        with locked(self, fcntl.LOCK_SH):
            return NUMBA_LOAD(self, key)

    def stamped_init(self, cache_path, filename_base, source_stamp):
        NUMBA_INIT(self, cache_path, filename_base, (source_stamp, source_digest()))

    locked_save._repro_locked = True
    IndexDataCacheFile.save, IndexDataCacheFile.load = locked_save, locked_load
    IndexDataCacheFile.__init__ = stamped_init
