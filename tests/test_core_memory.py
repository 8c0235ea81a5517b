"""keep_freed_memory: glibc's malloc keeps freed blocks; elsewhere it is a no-op."""

from __future__ import annotations

import platform

import pytest

from repro.core.memory import keep_freed_memory


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="a no-op without glibc")
def test_glibc_accepts_the_settings_and_a_second_call_changes_nothing():
    assert keep_freed_memory() is True
    assert keep_freed_memory() is True
