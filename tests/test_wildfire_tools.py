"""Heuristic policies, ADR, the wildfire-eval CLI and the PettingZoo wrapper."""

from __future__ import annotations

import json
import subprocess
import sys

from pathlib import Path

import numpy as np
import pytest

from repro.core.rollout import DecisionBatch, Rollout
from repro.envs.wildfire import WildfireConfig
from repro.envs.wildfire.policies import (FLOWCHART_HOLD_ALONE, FLOWCHART_HOLD_SHARED,
                                          FLOWCHART_TARGET, FlowchartPolicy, NearestPolicy,
                                          RandomPolicy)
from repro.studies.wildfire.study import adr

HOLD = 5
ROOT = Path(__file__).resolve().parents[1]


def obs_rows(fires: list[list[tuple[float, float, float]]]) -> DecisionBatch:
    """Observations whose observed fires are (distance, interest, alive), closest first."""
    obs = np.zeros((len(fires), 28))
    for r, fs in enumerate(fires):
        for k, (d, interest, alive) in enumerate(fs):
            obs[r, 2 + 5 * k:2 + 5 * k + 5] = [d, 1.0, interest, alive, 3.0]
    m = len(fires)
    return DecisionBatch(obs=obs, episode=np.zeros(m, int), agent=np.zeros(m, int),
                         index=np.arange(m))


FAR = [(0.5 + 0.1 * k, 0, 1) for k in range(5)]


def test_nearest_policy():
    batch = obs_rows([
        [(0.0, 1, 1)] + FAR[1:],  # at a live fire, only itself interested: hold
        [(0.0, 2, 1), (0.02, 0, 1)] + FAR[2:],  # another UAV there too: fly to the 2nd
        [(0.0, 1, 0), (0.02, 1, 1), (0.03, 0, 1)] + FAR[3:],  # out, taken: the 3rd
        [(0.3, 1, 1)] * 5,  # every fire has someone interested: random
    ])
    a = NearestPolicy(uniforms=lambda b: np.full((len(b), 2), 0.99))(batch)
    assert a.tolist() == [HOLD, 1, 2, HOLD]  # u = 0.99 -> random action 5


def test_flowchart_frequencies():
    rng = np.random.default_rng(0)
    n = 20000
    alone = obs_rows([[(0.0, 1, 1)] + FAR[1:]] * n)
    shared = obs_rows([[(0.0, 2, 1)] + FAR[1:]] * n)
    away = obs_rows([FAR] * n)
    pol = FlowchartPolicy(rng)
    for batch, p in ((alone, FLOWCHART_HOLD_ALONE), (shared, FLOWCHART_HOLD_SHARED), (away, 0.0)):
        a = pol(batch)
        assert abs(np.mean(a == HOLD) - p) < 0.015
        fly = a[a != HOLD]
        freq = np.bincount(fly, minlength=5) / len(fly)
        np.testing.assert_allclose(freq, FLOWCHART_TARGET, atol=0.015)


def test_random_policy_is_uniform():
    a = RandomPolicy(np.random.default_rng(1))(obs_rows([FAR] * 30000))
    np.testing.assert_allclose(np.bincount(a, minlength=6) / len(a), 1 / 6, atol=0.01)


def test_adr_is_the_mean_discounted_path_return():
    # two paths: rewards (1 at t=0, 2 at t=10) and (4 at t=0)
    r = Rollout(obs=np.zeros((3, 28)), actions=np.zeros(3, int), rewards=np.array([1., 2., 4.]),
                durations=np.array([10., 5., 7.]), path_start=np.array([0, 2, 3]),
                path_episode=np.zeros(2, int), path_agent=np.arange(2),
                episode_return=np.zeros(1))
    mean, err = adr(r, 0.02)
    paths = np.array([1 + np.exp(-0.2) * 2, 4.0])
    assert mean == pytest.approx(paths.mean())
    assert err == pytest.approx(paths.std(ddof=1) / np.sqrt(2))


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "repro", "wildfire-eval", *args],
                          capture_output=True, text=True)


def test_cli_json():
    res = cli("--policy", "nearest", "--sim", "fs", "--dt", "1", "--episodes", "20", "--json")
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    assert {"adr", "sem", "episodes", "decisions", "seconds"} <= set(out)
    assert out["episodes"] == 20 and out["sim"] == "FS-1" and out["adr"] > 0


@pytest.mark.parametrize("args", [
    ("--policy", "greedy"), ("--policy", "nearest", "--engine", "gpu"),
    ("--policy", "nearest", "--sim", "fs", "--dt", "0"),
    ("--policy", "nearest", "--t-health", "-1"), ("--policy", "nearest", "--episodes", "0"),
    ("--policy", "nearest", "--sim", "fs"), ("--policy", "nearest", "--sim", "ed", "--dt", "1"),
    ("--policy", "nearest", "--t-health", "inf"), ("--policy", "nearest", "--t-health", "nan"),
    ("--policy", "nearest", "--same-instant-order", "fifo"),
    ("--policy", "nearest", "--ranking-resolution", "-1e-9"),
    ("--policy", "nearest", "--ranking-resolution", "nan"),
])
def test_cli_bad_input(args, tmp_path, monkeypatch, capsys):
    from repro.cli import main

    monkeypatch.chdir(tmp_path)
    try:
        code = main(["wildfire-eval", *args])
    except SystemExit as exit_:  # argparse's errors
        code = exit_.code
    out, err = capsys.readouterr()
    assert code == 2
    assert out == "" and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv, expected", [
    ([], dict(dt=None, t_health=3.0, quirk_q1_stale_attack=True,
              quirk_q2_penalty_party_only=True, max_decisions=1000)),
    (["--no-quirk-q1", "--no-quirk-q2", "--max-decisions", "0"],
     dict(quirk_q1_stale_attack=False, quirk_q2_penalty_party_only=False, max_decisions=None)),
    ([], dict(quirk_q3_unclamped_health=True, quirk_q4_latency_not_interrupted=True,
              quirk_q5_discount_from_action_start=True, quirk_q6_short_flight_stays=True,
              same_instant_order="released", fs_round_negative_delays=True,
              cut_flight_continues=True, ranking_resolution=1e-9)),
    (["--no-quirk-q3", "--no-quirk-q4", "--no-quirk-q5", "--no-quirk-q6", "--same-instant-order",
      "scheduling", "--no-fs-round-negative-delays", "--no-cut-flight-continues",
      "--ranking-resolution", "0"],
     dict(quirk_q3_unclamped_health=False, quirk_q4_latency_not_interrupted=False,
          quirk_q5_discount_from_action_start=False, quirk_q6_short_flight_stays=False,
          same_instant_order="scheduling", fs_round_negative_delays=False,
          cut_flight_continues=False, ranking_resolution=0.0)),
    (["--sim", "fs", "--dt", "0.316", "--t-health", "2.9999", "--gamma", "0.05",
      "--max-decisions", "7"], dict(dt=0.316, t_health=2.9999, gamma=0.05, max_decisions=7)),
    (["--dt", "0.5", "--no-quirk-q3-unclamped-health", "--quirk-q4-latency-not-interrupted",
      "--max-decisions", "none"],
     dict(dt=0.5, quirk_q3_unclamped_health=False, quirk_q4_latency_not_interrupted=True,
          max_decisions=None)),
])
def test_command_line_options_give_the_config(argv, expected):
    import argparse

    from repro.envs.wildfire import add_env_arguments, config_from_args

    parser = argparse.ArgumentParser()
    add_env_arguments(parser)
    cfg = config_from_args(parser.parse_args(argv))
    assert {k: getattr(cfg, k) for k in expected} == expected


@pytest.mark.parametrize("field, value", [
    ("n_agents", 0), ("n_agents", 2.5), ("t_health", float("inf")), ("v_uav", float("inf")),
    ("decision_latency", 0.0), ("hold_mean", 0.0), ("hold_std", -0.1),
    ("hold_mean", float("nan")),
])
def test_bad_config_is_refused_naming_the_field(field, value):
    import dataclasses

    from repro.core.errors import UsageError

    with pytest.raises(UsageError, match=f"^-*{field.replace('_', '[-_]')}: "):
        dataclasses.replace(WildfireConfig(), **{field: value}).validate()


def test_pettingzoo_api():
    from pettingzoo.test import api_test

    from repro.envs.wildfire.pettingzoo_env import env

    api_test(env(WildfireConfig(dt=1.0)), num_cycles=200)


# four UAVs, as the race scenarios: each (N, K) compiles the fast engine anew (its state's layout)
@pytest.mark.parametrize("cfg", [WildfireConfig(), WildfireConfig(dt=1.0),
                                 WildfireConfig(quirk_q1_stale_attack=False,
                                                quirk_q2_penalty_party_only=False, n_agents=4)],
                         ids=["ed", "fs1", "corrected-4-uavs"])
def test_observations_lie_in_the_pettingzoo_observation_space(cfg):
    """Both engines' observations, over many random-policy episodes, within the wrapper's bounds
    (api_test checks only the few it sees)."""
    from repro.envs.wildfire import make_env, make_reference_env
    from repro.envs.wildfire.pettingzoo_env import observation_box

    box = observation_box(cfg)
    assert box.shape == (cfg.obs_dim,)
    for make, episodes in ((make_env, 400), (make_reference_env, 20)):
        ro = make(cfg).rollout(RandomPolicy(np.random.default_rng(1), n_observed=cfg.n_observed),
                               episodes, 2)
        assert np.all((ro.obs >= box.low) & (ro.obs <= box.high)), make.__name__


@pytest.mark.parametrize("engine", ["reference", "fast"])
def test_pettingzoo_rewards_match_the_reference(engine):
    """Driving the AEC env (on either engine) with an observation-driven policy reproduces the
    reference rollout of the same episode: every agent's observations, rewards and durations,
    decision by decision."""
    from repro.envs.wildfire import make_reference_env
    from repro.envs.wildfire.pettingzoo_env import env as make

    policy = NearestPolicy(uniforms=lambda b: np.full((len(b), 2), 0.5))
    e = make(engine=engine)
    e.reset(seed=3)
    paths = {a: {"obs": [], "rewards": [], "durations": []} for a in e.possible_agents}
    for agent in e.agent_iter():
        o, r, term, trunc, info = e.last()
        path = paths[agent]
        if path["obs"]:  # the reward and duration of the agent's previous decision
            path["rewards"].append(r)
            path["durations"].append(info["duration"])
        if term or trunc:
            e.step(None)
            continue
        path["obs"].append(o)
        e.step(int(policy(DecisionBatch(o[None], np.zeros(1, int), np.zeros(1, int),
                                        np.zeros(1, int)))[0]))
    ref = make_reference_env(WildfireConfig()).rollout(
        policy, 1, np.random.SeedSequence(3).spawn(1)[0])
    assert ref.n_decisions == sum(len(p["obs"]) for p in paths.values()) > 3
    for k, agent in enumerate(e.possible_agents):
        rows = slice(ref.path_start[k], ref.path_start[k + 1])
        assert ref.path_agent[k] == k
        for key, expected in (("obs", ref.obs.astype(np.float32)), ("rewards", ref.rewards),
                              ("durations", ref.durations)):
            np.testing.assert_allclose(np.array(paths[agent][key]), expected[rows], rtol=0,
                                       atol=1e-12, err_msg=f"{agent} {key}")


def test_evaluate_without_observations_keeps_everything_adr_needs(monkeypatch):
    from repro.envs.wildfire import make_env
    from repro.studies.wildfire import study as wildfire_eval

    monkeypatch.setattr(wildfire_eval, "BATCH_EPISODES", 10)  # several batches to join
    env = make_env(WildfireConfig())
    runs = {keep: wildfire_eval.evaluate(env, RandomPolicy(np.random.default_rng(1)), 25, 7,
                                         keep_obs=keep) for keep in (True, False)}
    full, slim = runs[True], runs[False]
    assert full.obs.shape[1] == 28 and slim.obs.shape == (full.n_decisions, 0)
    np.testing.assert_array_equal(slim.rewards, full.rewards)
    np.testing.assert_array_equal(slim.path_start, full.path_start)
    assert adr(slim, env.gamma) == adr(full, env.gamma)
