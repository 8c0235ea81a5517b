"""The released runner's sampler pool: W workers forked from one random state
(``TrainConfig.sampler = "released-pool"``).

What the released bus runner does (BusBunching/runner.sh, runners/rurllab.py; rllab's
sampler/parallel_sampler.py and stateful_pool.py; eventdriven/EDhelpers.py):

- It seeds nothing (``set_seed`` only with ``--seed``, which runner.sh does not give), and
  ``parallel_sampler.initialize(n_parallel=40)`` forks 40 workers that inherit the parent's numpy
  random state: every worker's stream is a copy of one stream, and each advances only by its own
  draws, from one epoch to the next.
- The bus simulator draws nothing (fixed travel times, rounded boarding); the only draws are the
  policy's, one uniform from numpy's global stream per decision (``special.weighted_sample``).
- Each epoch every worker runs whole episodes one after another; on finishing one it adds the
  decisions of all its agents' paths to a shared counter, and starts another only while the
  counter is short of the batch size. Every worker finishes the episode it has in flight, and the
  batch holds every worker's episodes, identical ones included: at a batch of 120 and about 240
  decisions per episode, 40 copies of one episode, which the baseline fit and the advantage
  standardisation weigh 40 times.

The model here: worker w's stream is the run's pool stream (a PCG64 generator) from position
``offsets[w]`` on; an episode started there draws the uniforms at ``offsets[w], offsets[w] + 1,
...``, one per decision in the engine's order, and moves the worker to the episode's end. Two
workers at one position run the same episode (the environment is deterministic and the policy
fixed within an epoch), so each position is simulated once and its episode copied into the batch
once per worker that ran it. Which worker starts another episode while the counter is short:
every decision costs the same CPU time and the host shares its cores fairly among the running
workers, so all running workers advance at one common rate and a worker's finish is ordered by
the decisions it has run this epoch (ties to the lower worker). The number of cores does not
enter: however many there are, the common rate changes every finish's time but not their order.
What the model leaves out is the host's jitter, which can reorder the finishes of two episodes of
nearly the same length; within a group of identical workers the order does not matter (they are
interchangeable), and the counter alone decides how many of the group start another.

Environments that draw random numbers themselves (the wildfire): the released wildfire runner was
unseeded too, and its simulator drew start positions and hold times from the same global stream
as the policy's actions. The model takes an environment whose randomness per episode is a fixed
number K of uniforms and which runs episodes on given draws (:class:`repro.core.rollout.
RunsOnDraws`): the episode that starts at position p takes the stream's uniforms p .. p + K - 1
for its own draws (the wildfire: its UAVs' starts, then their hold tables, the normal holds by the
inverse normal CDF, one uniform each, so that the stretch is fixed), then one uniform per decision
from p + K on, and moves its worker to p + K + its decisions. The episode stays a function of p
alone, so copies recur as on the bus; the counter still counts decisions, and finishes are still
ordered by decisions (the environment's draws cost no time worth counting). What this leaves out:
the released simulator drew each hold when it happened, between the policy's draws, and only as
many as the episode held, and drew normals by numpy's polar method (two uniforms a pair, some
rejected), so its episodes took stretches of varying length, interleaved; here the stretch is
fixed and the environment's part comes first. The released stream was unseeded, so no stretch of
it is reproduced either way: what the model keeps is that an episode is a function of where its
worker stands in one shared stream, and that workers move on by what their episodes took.
"""

from __future__ import annotations

import heapq
from typing import Callable

import numpy as np
from numba import njit

from repro.core.rollout import BatchEnv, DecisionBatch, Rollout, RunsOnDraws, RunsToEnd, concat

Acting = Callable[[DecisionBatch, np.ndarray], np.ndarray]
"""A policy's action for every row of a batch given one uniform per row
(:meth:`repro.learn.policy.Sampler.act`)."""


def collect(offsets: np.ndarray, lengths: dict[int, int], target: int,
            consumed: dict[int, int] | None = None
            ) -> tuple[list[tuple[int, int]], np.ndarray] | set[int]:
    """One epoch of the pool: the episodes (worker, start position), in the order of the released
    batch (by worker, each worker's in the order it ran them), and the workers' positions after
    the epoch. ``lengths`` holds the decisions of the episode that starts at each position known
    so far (they order the finishes and fill the counter), ``consumed`` the stream values it takes
    (they move its worker on; None: its decisions, an environment that draws nothing itself); if
    the epoch needs an episode it lacks, the result is instead the positions whose episodes the
    workers would start next and are not known (simulate them all, then call again)."""
    steps = lengths if consumed is None else consumed
    pos = offsets.astype(np.int64).copy()
    unknown = {int(o) for o in pos if int(o) not in lengths}
    if unknown:
        return unknown
    running = [(lengths[int(o)], w) for w, o in enumerate(pos)]  # (finish, worker)
    heapq.heapify(running)
    count, runs = 0, []
    while running:
        finish, w = heapq.heappop(running)
        start = int(pos[w])
        runs.append((w, start))
        pos[w] = start + steps[start]
        count += lengths[start]
        if count < target:  # this worker starts another episode
            nxt = int(pos[w])
            if nxt not in lengths:
                return {nxt, *(int(pos[v]) + steps[int(pos[v])] for _, v in running
                               if int(pos[v]) + steps[int(pos[v])] not in lengths)}
            heapq.heappush(running, (finish + lengths[nxt], w))
    runs.sort(key=lambda run: run[0])  # stable: each worker's episodes stay in order
    return runs, pos


def stream_uniforms(seed: np.random.SeedSequence, positions: list[int], k: int) -> np.ndarray:
    """(len(positions), k): row e the pool stream's ``k`` uniforms from ``positions[e]`` on."""
    return np.stack([np.random.Generator(np.random.PCG64(seed).advance(p)).random(k)
                     for p in positions]).reshape(len(positions), k)


def runs_on_pool(env: BatchEnv) -> bool:
    """Whether the pool can sample ``env``: it draws nothing itself (:class:`RunsToEnd`), or runs
    its episodes on given draws (:class:`RunsOnDraws`)."""
    return isinstance(env, (RunsOnDraws, RunsToEnd))


class EpisodeStreams:
    """The policy an engine calls for episodes that start at the pool stream's ``positions``:
    episode e's decisions draw, in the engine's order, the stream's uniforms from
    ``positions[e]`` on. Each episode's uniforms are drawn ahead in blocks (a generator gives the
    same numbers in blocks as one at a time), so that a round costs one compiled pass, as the
    independent sampler's does."""

    BLOCK = 512
    """Uniforms drawn ahead per episode at first (a bus episode makes about 225 decisions)."""

    def __init__(self, act: Acting, seed: np.random.SeedSequence, positions: list[int]):
        self.act = act
        self.streams = [np.random.Generator(np.random.PCG64(seed).advance(p)) for p in positions]
        self.drawn = np.stack([g.random(self.BLOCK) for g in self.streams])
        self.used = np.zeros(len(positions), np.int64)

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        u = np.empty(len(batch))
        while not _take_uniforms(self.drawn, self.used, batch.episode, u):
            width = self.drawn.shape[1]
            self.drawn = np.hstack([self.drawn, np.stack([g.random(width)
                                                          for g in self.streams])])
        return self.act(batch, u)


@njit(cache=True)
def _take_uniforms(drawn, used, episode, u):
    """Row r's uniform, the next unused one of its episode's ``drawn`` row, into ``u[r]``; False
    (and nothing taken) if an episode has too few left."""
    need = used.copy()
    for r in range(len(episode)):
        need[episode[r]] += 1
        if need[episode[r]] > drawn.shape[1]:
            return False
    for r in range(len(episode)):
        e = episode[r]
        u[r] = drawn[e, used[e]]
        used[e] += 1
    return True


def take_episodes(rollout: Rollout, episodes: np.ndarray) -> Rollout:
    """The ``episodes`` of ``rollout`` (indices, repeats allowed) as one rollout, in that order;
    ``info`` is not kept."""
    first = np.searchsorted(rollout.path_episode, episodes)
    last = np.searchsorted(rollout.path_episode, episodes, side="right")
    paths = np.concatenate([np.arange(a, b) for a, b in zip(first, last)]).astype(np.int64)
    lengths = np.diff(rollout.path_start)[paths]
    rows = np.concatenate([np.arange(rollout.path_start[p], rollout.path_start[p + 1])
                           for p in paths]).astype(np.int64)
    renumber = np.repeat(np.arange(len(episodes)), last - first)
    return Rollout(obs=rollout.obs[rows], actions=rollout.actions[rows],
                   rewards=rollout.rewards[rows], durations=rollout.durations[rows],
                   path_start=np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
                   path_episode=renumber, path_agent=rollout.path_agent[paths],
                   episode_return=rollout.episode_return[episodes],
                   truncated=None if rollout.truncated is None else rollout.truncated[episodes])


class ReleasedPool:
    """The workers' positions in the pool stream, kept across epochs (and in checkpoints), and
    the epoch's sampling (the module docstring says what it models)."""

    def __init__(self, seed: np.random.SeedSequence, workers: int):
        self.seed = seed
        self.offsets = np.zeros(workers, np.int64)
        """Each worker's position in the pool stream: the uniforms it has drawn so far."""

    def sample(self, env: BatchEnv, act: Acting, target: int) -> tuple[Rollout, int]:
        """The epoch's batch of at least ``target`` decisions, as the released pool collects it
        (identical episodes as copies), and how many distinct episodes (stream positions) it
        holds. Moves the workers on."""
        draws = env.draws_per_episode if isinstance(env, RunsOnDraws) else 0
        known: dict[int, int] = {}  # position -> episode index in ``chunks``
        lengths: dict[int, int] = {}  # position -> decisions
        consumed: dict[int, int] = {}  # position -> stream values
        chunks: list[Rollout] = []
        while True:
            result = collect(self.offsets, lengths, target, consumed)
            if not isinstance(result, set):
                break
            positions = sorted(result)
            chunk = self.simulate(env, act, positions)
            per_episode = np.bincount(chunk.path_episode, np.diff(chunk.path_start),
                                      minlength=len(positions)).astype(np.int64)
            if not per_episode.all():  # the counter would never reach the batch
                raise ValueError(f"{env.name}: an episode without decisions")
            for i, p in enumerate(positions):
                known[p] = sum(len(c.episode_return) for c in chunks) + i
                lengths[p] = int(per_episode[i])
                consumed[p] = draws + lengths[p]
            chunks.append(chunk)
        runs, self.offsets = result
        simulated = chunks[0] if len(chunks) == 1 else concat(chunks)
        starts = [start for _, start in runs]
        return take_episodes(simulated, np.array([known[s] for s in starts])), len(set(starts))

    def simulate(self, env: BatchEnv, act: Acting, positions: list[int]) -> Rollout:
        """The episodes that start at the pool stream's ``positions``: each takes the
        environment's draws from there on, then one uniform per decision."""
        if isinstance(env, RunsOnDraws):
            k = env.draws_per_episode
            return env.simulate(EpisodeStreams(act, self.seed, [p + k for p in positions]),
                                env.episode_draws(stream_uniforms(self.seed, positions, k)))
        return env.rollout(EpisodeStreams(act, self.seed, positions), len(positions), self.seed)
