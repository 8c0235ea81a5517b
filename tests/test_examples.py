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


@pytest.mark.parametrize("extra", [["--estimator", "m-gae"], ["--estimator", "gae"],
                                   ["--estimator", "m-gae", "--algorithm", "A2C"]])
def test_sb3_trains_through_the_parallel_env(extra):
    """SB3's PPO (and A2C), at a tiny budget, with M-GAE and with its own GAE: its updates run,
    their ADRs are finite, SB3's discount per decision comes from the batch's durations, and a
    seed repeats the run."""
    example = load("sb3_parallel_env")
    argv = ["--updates", "2", "--n-steps", "128", "--envs", "2", "--test-episodes", "20", "--seed",
            "3", *extra]
    result = example.main(argv)
    assert len(result["history"]) == 2 and np.isfinite(result["history"]).all()
    assert np.isfinite(result["test_adr"])
    assert (0 < result["gamma_d"] < 1) if "gae" in extra else result["gamma_d"] == 0
    assert example.main(argv) == result


def test_the_buffer_overhead_is_measured_for_both_buffers():
    medians = load("sb3_buffer_overhead").main(["--n-steps", "200", "--repeats", "1"])
    assert set(medians) == {"sb3", "m-gae"}
    assert all(s >= 0 for parts in medians.values() for s in parts.values())
