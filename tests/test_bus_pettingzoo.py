"""The AEC wrapper passes PettingZoo's API test and matches the batched engine."""

from __future__ import annotations

import numpy as np
from pettingzoo.test import api_test

from repro.envs.bus import BusConfig, make_env
from repro.envs.bus.pettingzoo_env import BusAECEnv
from repro.envs.bus.policies import no_holding


def test_api():
    api_test(BusAECEnv(), num_cycles=400)


def test_no_holding_return_matches_engine():
    env = BusAECEnv()
    env.reset()
    total = {a: 0.0 for a in env.possible_agents}
    for agent in env.agent_iter():
        _, reward, term, trunc, _ = env.last()
        total[agent] += reward
        env.step(None if term or trunc else 0)
    expected = make_env(BusConfig()).rollout(no_holding, 1).episode_return[0]
    np.testing.assert_allclose(list(total.values()), expected, rtol=1e-12)
