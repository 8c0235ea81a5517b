"""The corrected semantics (``--corrected``) reproduce the rollouts from before issue 23 exactly."""

from __future__ import annotations

import json

import pytest

from repro.envs.bus import BusConfig, make_env, make_reference_env
from tests.bus_scripted import FINGERPRINT, digests


@pytest.mark.parametrize("make", [make_env, make_reference_env], ids=["fast", "reference"])
def test_corrected_rollouts_match_the_fingerprint(make):
    expected = json.loads(FINGERPRINT.read_text())
    assert digests(make, BusConfig()) == expected
