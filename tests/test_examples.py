"""The examples run at a tiny budget, deterministically."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def load(name: str):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("argv", [["--env", "wildfire", "--n-envs", "8", "--paths", "40"],
                                  ["--env", "bus", "--n-envs", "2", "--paths", "6"]])
def test_reinforce_on_the_step_api_trains(argv):
    example = load("reinforce_step_api")
    history = example.main([*argv, "--updates", "2", "--seed", "3"])
    assert len(history) == 2 and np.isfinite(history).all()
    assert example.main([*argv, "--updates", "2", "--seed", "3"]) == history


def test_sb3_trains_through_the_parallel_env():
    """SB3's PPO, at a tiny budget: its updates run, their ADRs are finite, the discount per
    decision comes from the batch's durations, and a seed repeats the run."""
    example = load("sb3_parallel_env")
    argv = ["--updates", "2", "--n-steps", "128", "--test-episodes", "20", "--seed", "3"]
    result = example.main(argv)
    assert len(result["history"]) == 2 and np.isfinite(result["history"]).all()
    assert 0 < result["gamma_d"] < 1 and np.isfinite(result["test_adr"])
    assert example.main(argv) == result
