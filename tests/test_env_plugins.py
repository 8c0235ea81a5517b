"""An environment of the user's own, outside ``repro/``, trained by name: ``train --env
my_module`` takes any importable module that provides the environment contract
(:mod:`repro.envs`)."""

from __future__ import annotations

import json
import textwrap

import pandas as pd
import pytest

from repro.cli import main

PLUGIN = '''
"""Each agent decides every second for `horizon` seconds: action 0 pays 1, action 1 pays 0."""
import argparse
from dataclasses import dataclass

import numpy as np

from repro.core.rollout import DecisionBatch, Rollout

TRAIN_DEFAULTS = dict(lam=1.0, batch_episodes=16, epochs=5)


@dataclass(frozen=True)
class CoinConfig:
    horizon: int = 6
    gamma: float = 0.1


class CoinEnv:
    name = "coin"
    obs_dim, n_actions, n_agents = 1, 2, 2

    def __init__(self, cfg):
        self.cfg, self.gamma = cfg, cfg.gamma

    def rollout(self, policy, n_episodes, seed):
        e, a = np.meshgrid(np.arange(n_episodes), np.arange(self.n_agents), indexing="ij")
        e, a = e.ravel(), a.ravel()
        acts = np.stack([policy(DecisionBatch(obs=np.ones((len(e), 1)), episode=e, agent=a,
                                              index=np.full(len(e), k)))
                         for k in range(self.cfg.horizon)], axis=1)
        paid = (acts == 0).astype(float)
        return Rollout(obs=np.ones((acts.size, 1)), actions=acts.ravel(), rewards=paid.ravel(),
                       durations=np.ones(acts.size),
                       path_start=np.arange(0, acts.size + 1, self.cfg.horizon),
                       path_episode=e, path_agent=a,
                       episode_return=paid.reshape(n_episodes, -1).sum(axis=1))


def add_env_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--horizon", type=int, default=CoinConfig.horizon)


def config_from_args(args: argparse.Namespace) -> CoinConfig:
    return CoinConfig(horizon=args.horizon)


def make_env(cfg: CoinConfig) -> CoinEnv:
    return CoinEnv(cfg)
'''


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    (tmp_path / "my_envs").mkdir()
    (tmp_path / "my_envs" / "__init__.py").write_text("")
    (tmp_path / "my_envs" / "coin.py").write_text(textwrap.dedent(PLUGIN))
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


def test_train_takes_an_environment_module_from_outside_the_suite(plugin):
    out = plugin / "run"
    assert main(["train", "--env", "my_envs.coin", "--horizon", "4", "--learner", "suite",
                 "--out", str(out)]) == 0
    progress = pd.read_csv(out / "progress.csv")
    # its own defaults (5 epochs of 16 episodes for a learner that counts episodes), and it
    # learns to take the paying action
    assert len(progress) == 5 and (progress.batch_episodes == 16).all()
    assert progress.average_return.iloc[-1] > progress.average_return.iloc[0]
    config = json.loads((out / "config.json").read_text())
    assert config["env_name"] == "coin" and config["env"] == {"horizon": 4, "gamma": 0.1}
    # and resumes like a built-in one
    assert main(["train", "--env", "my_envs.coin", "--horizon", "4", "--epochs", "6",
                 "--learner", "suite", "--out", str(out)]) == 0
    assert len(pd.read_csv(out / "progress.csv")) == 6


@pytest.mark.parametrize("name", ["no_such_module", "my_envs.nothing", "json", ""])
def test_a_module_that_is_not_an_environment_is_one_line(plugin, capsys, name):
    assert main(["train", "--env", name, "--out", str(plugin / "run")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--env" in err and "importable module" in err
    assert not (plugin / "run").exists()
