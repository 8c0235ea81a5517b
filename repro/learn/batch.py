"""A batch counted in decisions, as the released runner sampled it.

rllab's parallel sampler (``rllab/sampler/stateful_pool.py``, ``run_collect``) runs
``n_parallel`` workers, each simulating whole episodes one after another; when a worker finishes
an episode it adds the episode's decisions to a shared count, and no worker starts a new episode
once the count has reached the batch size. Every worker finishes and keeps the episode it has in
flight, so a batch holds the episodes finished when the count was reached plus ``workers - 1``
longer-running ones, which are more often the long episodes.

The emulation here is deterministic: episodes are handed out in stream order to whichever worker is
free first (ties to the lower worker), and a worker spends on an episode a time proportional to the
episode's decisions. The episodes started before the count is reached are then a prefix of the
stream, :func:`episodes_started` says how long; :func:`sample` simulates the stream in chunks
until it is known, and keeps that prefix.
"""

from __future__ import annotations

import heapq

import numpy as np

from repro.core.rollout import BatchEnv, Policy, Rollout, concat, head


def episodes_started(decisions: np.ndarray, target: int, workers: int) -> int | None:
    """How many episodes of a stream whose episodes hold ``decisions`` (in stream order) the
    ``workers`` start before their finished episodes hold ``target`` decisions; None if the stream
    ends before that is known."""
    n = len(decisions)
    running = [(float(decisions[e]), e) for e in range(min(workers, n))]  # (finish time, episode)
    heapq.heapify(running)
    started, count = len(running), 0
    while running:
        now, e = heapq.heappop(running)
        count += int(decisions[e])
        if count >= target:
            return started
        if started == n:  # this worker would start an episode beyond the stream
            return None
        heapq.heappush(running, (now + float(decisions[started]), started))
        started += 1
    return None


def sample(env: BatchEnv, policy: Policy, target: int, workers: int,
           seed: np.random.SeedSequence) -> Rollout:
    """Whole episodes of ``env`` under ``policy``, as ``workers`` parallel workers collect a batch
    of at least ``target`` decisions. The stream is simulated in chunks (chunk j: ``workers * 2^j``
    episodes from the j-th child of ``seed``), so an epoch simulates at most about twice its
    batch."""
    chunks: list[Rollout] = []
    decisions = np.zeros(0, np.int64)
    while True:
        size = workers * 2 ** len(chunks)
        chunk = env.rollout(policy, size, np.random.SeedSequence(
            seed.entropy, spawn_key=(*seed.spawn_key, len(chunks))))
        chunks.append(chunk)
        per_episode = np.bincount(chunk.path_episode, np.diff(chunk.path_start).astype(float),
                                  minlength=size).astype(np.int64)
        decisions = np.concatenate([decisions, per_episode])
        n = episodes_started(decisions, target, workers)
        if n is not None:
            return head(concat(chunks) if len(chunks) > 1 else chunk, n)
