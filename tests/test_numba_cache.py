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


_ROLLOUTS = """
import itertools
import sys

import repro
from numba.core.bytecode import FunctionIdentity

from repro.envs.bus import make_env
from repro.envs.bus.params import BusConfig
from repro.envs.bus.policies import no_holding

if sys.argv[1] == "numba-ids":  # numba's own per-process counter: the suite without its fix
    FunctionIdentity._unique_ids = itertools.count(1)
for n in sys.argv[2:]:
    rollout = make_env(BusConfig(n_buses=int(n), horizon=600.0)).rollout(no_holding, 2, 0)
    print(n, len(rollout.actions), rollout.rewards.sum())
"""
SIZES = (3, 6)
"""Two record layouts of the bus engine (the number of buses sizes its state's fields)."""


def _rollouts(cache: Path, ids: str, *n_buses: int) -> subprocess.CompletedProcess:
    """Bus rollouts with ``n_buses`` buses in a fresh process that caches its kernels into
    ``cache``, with numba's compilation ids drawn by the suite ("suite") or by numba's own
    counter ("numba-ids")."""
    return subprocess.run([sys.executable, "-c", _ROLLOUTS, ids, *map(str, n_buses)],
                          env=dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT)),
                          capture_output=True, text=True, timeout=600)


def _compiled_apart_then_loaded_together(cache: Path, ids: str
                                         ) -> tuple[str, subprocess.CompletedProcess]:
    """The engine compiled for each of SIZES in a process of its own, as the test suite's
    commands and workers fill the cache, then loaded together by another, as a study does: what
    the processes alone printed, and the last one."""
    alone = [_rollouts(cache, ids, n) for n in SIZES]
    assert all(p.returncode == 0 for p in alone), [p.stderr[-2000:] for p in alone]
    return "".join(p.stdout for p in alone), _rollouts(cache, ids, *SIZES)


@pytest.mark.timeout(900)
def test_engines_cached_by_separate_processes_load_together(tmp_path):
    """Each layout runs its own code when kernels compiled by separate processes are loaded
    together (the suite's random compilation ids give each compilation a symbol of its own)."""
    alone, together = _compiled_apart_then_loaded_together(tmp_path, "suite")
    assert together.returncode == 0, together.stderr[-2000:]
    assert together.stdout == alone


@pytest.mark.timeout(900)
def test_with_numbas_own_ids_one_layout_runs_the_others_code(tmp_path):
    """The failure the random ids prevent: with numba's per-process counter both compilations
    get one symbol, and the process that loads both runs the first layout's code on the second's
    records (here its episodes end without a decision; the wildfire engine crashed, SIGSEGV)."""
    alone, together = _compiled_apart_then_loaded_together(tmp_path, "numba-ids")
    assert together.returncode != 0 or together.stdout != alone


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
