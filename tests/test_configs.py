"""Every config validates itself on construction: no config with a bad value exists."""

from __future__ import annotations

import dataclasses

import pytest

from repro.core.errors import UsageError
from repro.envs.bus import BusConfig
from repro.envs.toy import ToyConfig
from repro.envs.wildfire import WildfireConfig
from repro.experiments.race import RaceConfig
from repro.experiments.transfer import TransferConfig
from repro.learn.config import TrainConfig


@pytest.mark.parametrize("make, param", [
    (lambda: WildfireConfig(n_agents=-3), "--n-agents"),
    (lambda: dataclasses.replace(WildfireConfig(), t_health=0.0), "--t-health"),
    (lambda: BusConfig(n_buses=0), "--n-buses"),
    (lambda: ToyConfig(n_agents=0), "--n-agents"),
    (lambda: TrainConfig(epochs=0), "--epochs"),
    (lambda: RaceConfig(n_sets=0), "--n-sets"),
    (lambda: TransferConfig(seeds=0), "--seeds"),
])
def test_a_bad_value_cannot_be_constructed(make, param):
    with pytest.raises(UsageError, match=param):
        make()
