"""numba's cache (repro.runs.numba_cache): two writers of one function's cache that read its index
at the same time must not both take one data file, and kernels compiled by different processes
must not share a symbol."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from numba.core.caching import IndexDataCacheFile

import repro  # noqa: F401  (installs the lock, as every process of the suite does)
from repro.runs import numba_cache

pytestmark = pytest.mark.slow  # studies end to end, subprocesses: left out of make test-fast

ROOT = Path(__file__).resolve().parents[1]


def _save_concurrently(tmp_path, monkeypatch) -> dict:
    read = IndexDataCacheFile._load_index

    def slow_read(self):  # both writers read the index before either writes it
        overloads = read(self)
        time.sleep(0.3)
        return overloads

    monkeypatch.setattr(IndexDataCacheFile, "_load_index", slow_read)
    files = [IndexDataCacheFile(str(tmp_path), "kernel-1.py311", b"stamp") for _ in range(2)]
    threads = [threading.Thread(target=f.save, args=(f"signature {i}", f"code {i}"))
               for i, f in enumerate(files)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    monkeypatch.setattr(IndexDataCacheFile, "_load_index", read)
    return {key: files[0].load(key) for key in ("signature 0", "signature 1")}


def test_concurrent_saves_keep_each_signature_with_its_own_code(tmp_path, monkeypatch):
    assert getattr(IndexDataCacheFile.save, "_repro_locked", False)
    assert _save_concurrently(tmp_path, monkeypatch) == {"signature 0": "code 0",
                                                         "signature 1": "code 1"}


def test_without_the_lock_one_signature_gets_the_others_code(tmp_path, monkeypatch):
    """The failure the lock prevents (numba issue 4807), shown on numba's own save."""
    monkeypatch.setattr(IndexDataCacheFile, "save", numba_cache.NUMBA_SAVE)
    loaded = _save_concurrently(tmp_path, monkeypatch)
    assert loaded != {"signature 0": "code 0", "signature 1": "code 1"}


_CELLS = """
import sys
import repro
from repro.studies.races.wildfire_races import cell
for n in sys.argv[1:]:
    r = cell("nearest", int(n), -1.0, 2, 0)
    print(n, r["decisions"], r["races"])
"""


def _cells(cache: Path, *n_agents: int) -> subprocess.CompletedProcess:
    """beyond-races' cells of ``n_agents`` UAVs in a fresh process that caches into ``cache``."""
    return subprocess.run([sys.executable, "-c", _CELLS, *map(str, n_agents)],
                          env=dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT)),
                          capture_output=True, text=True, timeout=600)


@pytest.mark.timeout(900)
def test_engines_cached_by_separate_processes_load_together(tmp_path):
    """The wildfire engine compiled for three N in three processes (the fewest that crash without
    the fix), as the test suite's commands and workers fill the cache, then loaded together by a
    fourth, as a study does: each N must run its own code. With numba's per-process compilation
    counter the three compilations had one symbol, and the fourth process crashed in the engine's
    set-up (SIGSEGV)."""
    alone = [_cells(tmp_path, n) for n in (3, 6, 12)]
    assert all(p.returncode == 0 for p in alone), [p.stderr[-2000:] for p in alone]
    together = _cells(tmp_path, 3, 6, 12)
    assert together.returncode == 0, together.stderr[-2000:]
    assert together.stdout == "".join(p.stdout for p in alone)


def test_a_source_change_a_kernel_can_see_makes_cached_kernels_stale(tmp_path, monkeypatch):
    """numba stamps a cache with its function's own file only; the suite's stamp also holds the
    digest of the source kernels can see, so a kernel cached before a callee in another file
    changed is not loaded after the change; a change to a study leaves the cache valid."""
    package = tmp_path / "pkg"
    for part in ("envs", "studies"):
        (package / part).mkdir(parents=True)
    (package / "paper.py").write_text("x = 1\n")
    (package / "envs" / "b.py").write_text("y = 2\n")
    (package / "studies" / "c.py").write_text("z = 3\n")
    before = numba_cache.source_digest(package)
    assert numba_cache.source_digest(package) == before
    (package / "studies" / "c.py").write_text("z = 4\n")
    numba_cache.source_digest.cache_clear()
    assert numba_cache.source_digest(package) == before
    (package / "envs" / "b.py").write_text("y = 3\n")
    numba_cache.source_digest.cache_clear()
    after = numba_cache.source_digest(package)
    assert after != before
    assert set(numba_cache.KERNEL_SOURCES) >= {p.name for p in numba_cache.PACKAGE.iterdir()
                                               if p.name not in ("studies", "claims", "cli.py",
                                                                 "reproduce.py", "__main__.py",
                                                                 "__pycache__")}

    def cache_file():
        return IndexDataCacheFile(str(tmp_path), "kernel-1.py311", b"stamp")

    monkeypatch.setattr(numba_cache, "source_digest", lambda: before)
    cache_file().save("signature", "old code")
    assert cache_file().load("signature") == "old code"
    monkeypatch.setattr(numba_cache, "source_digest", lambda: after)
    assert cache_file().load("signature") is None  # stale: compiled anew
