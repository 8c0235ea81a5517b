"""numba's cache file under concurrent saves (repro.runs.numba_cache): two writers of one
function's cache that read its index at the same time must not both take one data file."""

from __future__ import annotations

import threading
import time

from numba.core.caching import IndexDataCacheFile

import repro  # noqa: F401  (installs the lock, as every process of the suite does)
from repro.runs import numba_cache


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
