"""Scripted bus policies keyed by (episode, agent, decision number), and rollout digests.

A scripted action depends only on which decision it answers, never on how the engine batches the
decisions, so two engines (or the authors' released simulator) can be driven with the same
actions. ``python -m tests.bus_scripted`` writes the fingerprint fixture of the corrected
semantics (``--corrected``): the digests of today's rollouts, taken before the released semantics
became the default (issue 23), which the corrected switches must keep reproducing.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from repro.core.rollout import DecisionBatch

FINGERPRINT = Path(__file__).parent / "data" / "bus_corrected_fingerprint.json"
SCRIPTS = ("nohold", "uniform", "long-holds")
"""No holding; uniform over the 4 actions; mostly 0 with some a = 3 holds (1 in 8)."""
MAX_DECISIONS = 256
"""Decisions per agent and episode a script covers (a 6 h episode has about 110)."""


def action_table(script: str, seed: int, n_episodes: int, n_agents: int) -> np.ndarray:
    """(E, N, MAX_DECISIONS) actions: [e, i, k] answers agent i's k-th decision in episode e."""
    rng = np.random.default_rng(seed)
    shape = (n_episodes, n_agents, MAX_DECISIONS)
    if script == "nohold":
        return np.zeros(shape, np.int64)
    if script == "uniform":
        return rng.integers(0, 4, shape)
    if script == "long-holds":
        return np.where(rng.random(shape) < 0.125, 3, 0)
    raise ValueError(script)


class Scripted:
    """A policy that plays an action table."""

    def __init__(self, table: np.ndarray):
        self.table = table

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        return self.table[batch.episode, batch.agent, batch.index]


CASES = [(script, seed) for script in SCRIPTS for seed in (0, 1)]
N_EPISODES = 3


def digests(make_env, cfg) -> dict[str, str]:
    """sha256 of every rollout array, per (engine's env maker, script, seed), 3 episodes each."""
    out = {}
    for script, seed in CASES:
        table = action_table(script, seed, N_EPISODES, cfg.n_buses)
        roll = make_env(cfg).rollout(Scripted(table), N_EPISODES)
        for name in ("obs", "actions", "rewards", "durations", "path_start", "episode_return"):
            arr = np.ascontiguousarray(getattr(roll, name))
            out[f"{script}/{seed}/{name}"] = hashlib.sha256(arr.tobytes()).hexdigest()
    return out


if __name__ == "__main__":
    from repro.envs.bus import BusConfig, make_env, make_reference_env

    fast = digests(make_env, BusConfig())
    assert fast == digests(make_reference_env, BusConfig())
    FINGERPRINT.parent.mkdir(exist_ok=True)
    FINGERPRINT.write_text(json.dumps(fast, indent=1, sort_keys=True) + "\n")
    print(f"wrote {FINGERPRINT} ({len(fast)} digests)")
