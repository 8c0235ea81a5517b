"""The corrected semantics (``--corrected``: B1-B5 off) reproduce, bit for bit, the rollouts from
before issue 23 made the released semantics the default (fixture written by tests/bus_scripted.py
before any engine change)."""

from __future__ import annotations

import json

import pytest

from repro.envs.bus import BusConfig, make_env, make_reference_env
from tests.bus_scripted import FINGERPRINT, digests

ENGINES = pytest.mark.parametrize("make", [make_env, make_reference_env],
                                  ids=["fast", "reference"])


@ENGINES
def test_corrected_rollouts_match_the_fingerprint(make):
    assert digests(make, BusConfig.corrected()) == json.loads(FINGERPRINT.read_text())


@ENGINES
def test_the_default_is_not_the_corrected_semantics(make):
    """The check can fail: the released default changes every rollout array but the actions."""
    expected = json.loads(FINGERPRINT.read_text())
    got = digests(make, BusConfig())
    assert all(got[k] != v for k, v in expected.items()
               if not k.endswith(("/actions", "/path_start")))
