"""Both environments' PettingZoo views follow one convention (repro.core.parallel_env): env(),
raw_env() and parallel_env(), render modes, clean API tests; a ParallelEnv whose agents deciding
at one round act together; in both APIs rewards that are M-GAE's r_k (each macro-action's rewards
discounted to its start, per agent), infos with the macro-action's ``duration`` and the clock
``time`` at its end, float32 observations within their spaces, the horizon as termination and the
decision limit as truncation."""

from __future__ import annotations

import importlib
import warnings

import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, render_test, seed_test

from repro.core.errors import UsageError
from repro.envs.bus import BusConfig
from repro.envs.bus import make_env as bus_engine
from repro.envs.wildfire import WildfireConfig
from repro.envs.wildfire import make_env as wildfire_engine

MODULES = ["repro.envs.wildfire.pettingzoo_env", "repro.envs.bus.pettingzoo_env"]


def no_user_warnings(test, *args, **kwargs) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        test(*args, **kwargs)
    assert not [str(w.message) for w in caught if issubclass(w.category, UserWarning)]


@pytest.mark.parametrize("name, options", [(MODULES[0], {}), (MODULES[0], {"engine": "fast"}),
                                           (MODULES[1], {})])
def test_api_test_passes_without_warnings(name, options):
    module = importlib.import_module(name)
    no_user_warnings(api_test, module.env(**options), num_cycles=100)


# four UAVs, as the race scenarios: each (N, K) compiles the fast engine anew (its state's layout)
@pytest.mark.parametrize("name, cfg", [
    (MODULES[0], WildfireConfig()), (MODULES[0], WildfireConfig(dt=1.0, max_decisions=3)),
    (MODULES[0], WildfireConfig(quirk_q4_latency_not_interrupted=False, n_agents=4)),
    (MODULES[1], BusConfig())])
def test_parallel_api_test_passes_without_warnings(name, cfg):
    module = importlib.import_module(name)
    no_user_warnings(parallel_api_test, module.parallel_env(cfg), num_cycles=100_000)


@pytest.mark.parametrize("name, options", [(MODULES[0], {}), (MODULES[0], {"engine": "fast"}),
                                           (MODULES[1], {})])
def test_a_seed_repeats_an_episode(name, options):
    module = importlib.import_module(name)
    seed_test(lambda: module.env(**options), num_cycles=100)
    if not options:
        parallel_seed_test(module.parallel_env, num_cycles=100)


@pytest.mark.parametrize("name", MODULES)
def test_one_naming_scheme(name):
    module = importlib.import_module(name)
    raw = module.raw_env()
    env_name = name.split(".")[2]
    assert raw.metadata["name"] == f"{env_name}_v0"
    assert type(raw).__name__.endswith("AECEnv")
    assert type(module.parallel_env()).__name__.endswith("ParallelEnv")
    assert module.env().unwrapped.metadata == raw.metadata
    assert module.parallel_env().metadata["name"] == raw.metadata["name"]
    assert raw.metadata["render_modes"] == ["human", "rgb_array"]
    assert module.parallel_env().possible_agents == raw.possible_agents


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
    with pytest.raises(UsageError):
        module.parallel_env(render_mode="ansi")


@pytest.mark.parametrize("name", MODULES)
def test_the_parallel_env_renders(name):
    env = importlib.import_module(name).parallel_env(render_mode="rgb_array")
    obs, _ = env.reset(seed=1)
    first = env.render().copy()
    for _ in range(10):
        obs, *_ = env.step({a: 0 for a in obs})
    later = env.render()
    env.close()
    assert first.shape == (360, 720, 3) and (first != later).any()


def by_decision(agent: np.ndarray, index: np.ndarray, n_actions: int) -> np.ndarray:
    """A deterministic policy of the agent and its decision number (so that float32 and float64
    observations choose alike): the actions vary decision by decision."""
    return (3 * agent + 7 * index + 1) % n_actions


CASES = [("wildfire", WildfireConfig()), ("wildfire", WildfireConfig(dt=1.0, max_decisions=3)),
         ("bus", BusConfig())]


def engine_rollout(env_name: str, cfg, seed: int):
    """The engine's rollout of the episode that ``reset(seed=seed)`` starts, under
    :func:`by_decision`."""
    engine = (wildfire_engine if env_name == "wildfire" else bus_engine)(cfg)

    def policy(batch):
        return by_decision(batch.agent, batch.index, cfg.n_actions)

    return engine.rollout(policy, 1, np.random.SeedSequence(seed).spawn(1)[0])


def expected_paths(ro, agents: list[str]) -> dict[str, dict[str, np.ndarray]]:
    paths = {}
    for p in range(ro.n_paths):
        rows = slice(ro.path_start[p], ro.path_start[p + 1])
        paths[agents[ro.path_agent[p]]] = {
            "obs": ro.obs[rows], "reward": ro.rewards[rows], "duration": ro.durations[rows],
            "time": np.cumsum(ro.durations[rows])}
    return paths


def assert_paths_match(seen: dict, ro, agents: list[str]) -> None:
    expected = expected_paths(ro, agents)
    assert sorted(seen) == sorted(expected) and ro.n_decisions > len(agents)
    for a, path in expected.items():
        for key, want in path.items():
            got = np.array(seen[a][key])
            assert got.shape == want.shape, (a, key)
            if key == "obs":
                assert got.dtype == np.float32
                np.testing.assert_array_equal(got, want.astype(np.float32), err_msg=a)
            else:
                np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-9, err_msg=(a, key))


@pytest.mark.parametrize("env_name, cfg", CASES, ids=["wildfire", "wildfire-limit", "bus"])
def test_parallel_steps_give_each_agent_its_macro_actions(env_name, cfg):
    """Driven by one policy, the ParallelEnv hands out exactly the engine rollout's decisions,
    per agent in order, with their M-GAE rewards, durations and end times; the episode ends as
    the engine's, terminated at its horizon, truncated at the decision limit; every agent
    finishes."""
    module = importlib.import_module(f"repro.envs.{env_name}.pettingzoo_env")
    env = module.parallel_env(cfg)
    obs, infos = env.reset(seed=5)
    seen = {a: {"obs": [o], "reward": [], "duration": [], "time": []} for a, o in obs.items()}
    space = env.observation_space(env.possible_agents[0])
    ended = {}
    while env.agents:
        deciding = [a for a in obs if infos[a]["decides"]]
        assert set(deciding) <= set(env.agents)
        actions = {a: int(by_decision(np.array(env.possible_agents.index(a)),
                                      np.array(len(seen[a]["obs"]) - 1), cfg.n_actions))
                   for a in deciding}
        obs, rewards, terms, truncs, infos = env.step(actions)
        for a, o in obs.items():
            assert space.contains(o), (a, o)
            path = seen.setdefault(a, {"obs": [], "reward": [], "duration": [], "time": []})
            if terms[a] or truncs[a] or (infos[a]["decides"] and path["obs"]):
                path["reward"].append(rewards[a])
                path["duration"].append(infos[a]["duration"])
                path["time"].append(infos[a]["time"])
            elif not infos[a]["decides"]:
                assert rewards[a] == 0 and infos[a]["duration"] == 0
            if infos[a]["decides"]:
                path["obs"].append(o)
            if terms[a] or truncs[a]:
                ended[a] = (terms[a], truncs[a])
    ro = engine_rollout(env_name, cfg, 5)
    assert_paths_match(seen, ro, env.possible_agents)
    truncated = bool(ro.truncated[0]) if ro.truncated is not None else False
    assert set(ended.values()) == {(not truncated, truncated)}
    if cfg == CASES[1][1]:
        assert truncated  # the limit of 3 decisions cuts the episode


@pytest.mark.parametrize("env_name, options", [("wildfire", {"engine": "fast"}),
                                               ("wildfire", {}), ("bus", {})])
def test_aec_rewards_and_infos_follow_the_convention(env_name, options):
    """The AEC env on the same episode: the selected agent's reward and info are those of its
    macro-action that ended with this decision; at the end, those of its last one."""
    module = importlib.import_module(f"repro.envs.{env_name}.pettingzoo_env")
    cfg = WildfireConfig() if env_name == "wildfire" else BusConfig()
    env = module.env(cfg, **options)
    env.reset(seed=5)
    seen = {a: {"obs": [], "reward": [], "duration": [], "time": []} for a in env.possible_agents}
    ended = set()
    for agent in env.agent_iter():
        o, r, term, trunc, info = env.last()
        path = seen[agent]
        if path["obs"]:
            path["reward"].append(r)
            path["duration"].append(info["duration"])
            path["time"].append(info["time"])
        else:
            assert r == 0 and info == {"duration": 0.0, "time": 0.0}
        if term or trunc:
            ended.add((term, trunc))
            env.step(None)
            continue
        path["obs"].append(o)
        env.step(int(by_decision(np.array(env.possible_agents.index(agent)),
                                 np.array(len(path["obs"]) - 1), cfg.n_actions)))
    assert ended == {(True, False)}
    assert_paths_match({a: p for a, p in seen.items() if p["obs"]},
                       engine_rollout(env_name, cfg, 5), env.possible_agents)


def test_actions_missing_for_a_deciding_agent_are_refused():
    from repro.envs.bus.pettingzoo_env import parallel_env

    env = parallel_env()
    obs, _ = env.reset()
    with pytest.raises(UsageError, match="^actions: "):
        env.step({})


@pytest.mark.parametrize("name", MODULES)
def test_spaces_are_float32(name):
    module = importlib.import_module(name)
    for env in (module.raw_env(), module.parallel_env()):
        space = env.observation_space(env.possible_agents[0])
        assert space.dtype == np.float32 and (space.low < space.high).all()
