"""The AEC wrapper passes PettingZoo's API test and matches the batched engine."""

from __future__ import annotations

import numpy as np
from pettingzoo.test import api_test

from repro.envs.bus import BusConfig, make_env
from repro.envs.bus.pettingzoo_env import BusAECEnv
from repro.envs.bus.policies import no_holding


def test_api():
    api_test(BusAECEnv(), num_cycles=400)


def test_no_holding_rewards_match_the_engine():
    """Each bus's AEC rewards are its macro-actions' (discounted to their starts): summed along
    its path with the discount to t = 0 they are the rollout's discounted path return."""
    env = BusAECEnv()
    env.reset()
    total = {a: 0.0 for a in env.possible_agents}
    for agent in env.agent_iter():
        _, reward, term, trunc, info = env.last()
        # the reward's macro-action started at time - duration
        total[agent] += np.exp(-env.cfg.gamma * (info["time"] - info["duration"])) * reward
        env.step(None if term or trunc else 0)
    ro = make_env(BusConfig()).rollout(no_holding, 1)
    np.testing.assert_allclose(list(total.values()), ro.discounted_path_returns(env.cfg.gamma),
                               rtol=1e-12)


def test_observations_lie_in_the_observation_space():
    """Both engines' observations, over many episodes of random holding, within the wrapper's
    bounds (api_test checks only the few it sees)."""
    from repro.envs.bus import make_reference_env

    rng = np.random.default_rng(0)

    def random_holds(batch):
        return rng.integers(0, 4, len(batch))

    space = BusAECEnv().observation_space("bus_0")
    for make, episodes in ((make_env, 200), (make_reference_env, 5)):
        ro = make(BusConfig()).rollout(random_holds, episodes, 3)
        assert np.all((ro.obs >= space.low) & (ro.obs <= space.high)), make.__name__
