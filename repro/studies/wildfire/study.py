"""The wildfire's evaluation, which every study that tests a wildfire policy shares: the ADR of a
policy over many episodes, simulated in batches."""

from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np

from repro.core.rollout import Policy, Rollout, concat, rollout_bytes
from repro.runs.memory import require_memory
from repro.runs.stats import sem


BATCH_EPISODES = 1000
"""Episodes per engine call (bounds memory; the fast engine's throughput is flat beyond this)."""


def adr(rollout: Rollout, gamma: float) -> tuple[float, float]:
    """Average discounted return over all paths, and its standard error."""
    r = rollout.discounted_path_returns(gamma)
    return float(np.mean(r)), sem(r)


def evaluate(env, policy: Policy, n_episodes: int, seed: int, keep_obs: bool = True,
             on_batch: Callable[[Rollout], object] | None = None,
             param: str = "--test-episodes") -> Rollout:
    """Roll out ``n_episodes`` in batches seeded from children of ``seed``. ``keep_obs=False`` drops
    each batch's observations and engine log (``info``) as soon as it is done (the result's ``obs``
    has 0 columns): ADR does not need them, and a learned policy that keeps flying to the fire it is
    at can take tens of millions of decisions over 10,000 test episodes; with their observations,
    one paper-scale transfer test filled the machine's 24 GB. ``on_batch`` sees each whole batch
    first. A number of episodes whose rollouts cannot fit in memory is refused first
    (UsageError naming ``param``)."""
    require_memory(rollout_bytes(env, n_episodes, keep_obs=keep_obs, batch=BATCH_EPISODES),
                   param, n_episodes, "the rollouts")
    n_batches = -(-n_episodes // BATCH_EPISODES)
    children = np.random.SeedSequence(seed).spawn(n_batches)
    sizes = [min(BATCH_EPISODES, n_episodes - c * BATCH_EPISODES) for c in range(n_batches)]
    batches = []
    for n, ss in zip(sizes, children):
        batch = env.rollout(policy, n, ss)
        if on_batch is not None:
            on_batch(batch)
        batches.append(batch if keep_obs else replace(batch, obs=batch.obs[:, :0], info={}))
    return concat(batches)
