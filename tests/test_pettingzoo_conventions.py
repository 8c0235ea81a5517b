"""Both PettingZoo views follow one convention: env() and raw_env(), render modes, a clean
api_test."""

from __future__ import annotations

import importlib
import warnings

import numpy as np
import pytest
from pettingzoo.test import api_test, render_test

from repro.core.errors import UsageError

MODULES = ["repro.envs.wildfire.pettingzoo_env", "repro.envs.bus.pettingzoo_env"]


@pytest.mark.parametrize("name, options", [(MODULES[0], {}), (MODULES[0], {"engine": "fast"}),
                                           (MODULES[1], {})])
def test_api_test_passes_without_warnings(name, options):
    module = importlib.import_module(name)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        api_test(module.env(**options), num_cycles=100)
    assert not [str(w.message) for w in caught if issubclass(w.category, UserWarning)]


@pytest.mark.parametrize("name", MODULES)
def test_one_naming_scheme(name):
    module = importlib.import_module(name)
    raw = module.raw_env()
    env_name = name.split(".")[2]
    assert raw.metadata["name"] == f"{env_name}_v0"
    assert type(raw).__name__.endswith("AECEnv")
    assert module.env().unwrapped.metadata == raw.metadata
    assert raw.metadata["render_modes"] == ["human", "rgb_array"]


@pytest.mark.parametrize("name", MODULES)
def test_renders_pictures_of_the_state(name):
    module = importlib.import_module(name)
    render_test(module.raw_env)  # both modes, a few steps apart
    env = module.raw_env(render_mode="rgb_array")
    env.reset(seed=1)
    first = env.render()
    for _ in range(3 * len(env.possible_agents)):
        env.step(0 if not (env.terminations[env.agent_selection]
                           or env.truncations[env.agent_selection]) else None)
    later = env.render()
    env.close()
    assert first.shape == (360, 720, 3) and first.dtype == np.uint8
    assert first.std() > 10  # a drawing, not a blank
    assert (first != later).any()  # the state moved on
    with pytest.raises(UsageError):
        module.raw_env(render_mode="ansi")
