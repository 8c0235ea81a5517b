"""What the engine benchmarks (``bench-bus``, ``bench-wildfire``) share: sizes, policies, timing.

A benchmark runs an environment's fast engine and its SimPy reference under two policies:

- each learner's policy (:data:`~repro.learn.config.LEARNERS`) exactly as training runs it, a
  fresh :class:`CategoricalPolicy` evaluated by the :class:`Sampler` the trainer hands to the
  engines (each round's decisions in compiled code, inverse-CDF sampling): policy
  ``authors-mlp-32-tanh``, the authors' network (one hidden layer of 32, Glorot-uniform weights),
  and ``suite-mlp-32x32-tanh``, the suite's (two of 32, orthogonal weights). Where a learner
  normalises observations, its normaliser is fitted to the warm-up rollout, as the trainer's is
  after its first epoch;
- a cheap policy of the environment, which shows what the engine costs nearly alone.

The fast engine's step API (``make_vector_env``, engine ``fast-step-api``) runs both policies too
(one call per step), on as many envs as the fast engine's batch has episodes, stepped until it has
made as many decisions per batch as the rollouts of that policy did (ended episodes restart, so the
batch stays full). Under the cheap policy its rate against the rollouts' shows what driving the
engine step by step costs. At that horizon the step API has also drawn the randomness of the
episodes still running when it stops (a wildfire episode's start positions and whole hold table are
drawn when it starts), which the rollouts do not.

With ``--checkpoint PATH`` (a training run's ``checkpoint.pt``) the trained policy, with its own
normaliser, takes the fresh networks' place (policy ``checkpoint``), and both engines run that
run's environment settings; the CSV is then ``bench_<env>_checkpoint.csv``. Trained policies can
make episodes far longer than a fresh one's (see the stay flights of the wildfire's C6 runs),
which is a different regime for the engine.

Each engine runs ``repeats`` batches per policy: the fast engine batches of ``fast_episodes`` (the
environment's training batch), the reference smaller ones (its cost per episode does not depend on
the batch). Batch r draws its episodes from child r of the seed, and each engine gets the same
freshly seeded sampler. The warm-up rollout also compiles the fast engine (or loads it from cache).
Everything runs on one thread, as in training.

Rates are per second of this process's CPU time, which is what one core achieves when the machine
is shared, and per wall second; each is the median over the batches, as other processes' bursts of
load on a shared machine slow single batches by up to 3x, even in CPU time. Counts and seconds are
totals. ``policy_cpu_seconds`` is the time inside the policy's calls, about the same
per decision for both engines: ``speedup_vs_reference`` compares whole rollouts (decisions per CPU
second), ``engine_speedup_vs_reference`` the time outside the policy's calls, what the engine
itself costs.
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import dataclass, fields
from functools import partial
from typing import Any, Callable

import numpy as np
import pandas as pd

from repro.core.config import Validated, add_config_arguments, for_scale, given_fields
from repro.core.rollout import BatchEnv, DecisionBatch, Policy, rollout_bytes
from repro.envs import env_package, make_vector_env, train_defaults
from repro.learn.config import LEARNERS
from repro.learn.trained_policy import check_fits, load_trained_run, policy_from_state
from repro.runs.memory import require_memory
from repro.runs.provenance import provenance
from repro.runs.results import write_result
from repro.studies.kit.options import Command, Folders, add_common


CheapPolicy = Callable[[BatchEnv, np.random.Generator], Policy]
"""Makes an environment's cheap policy from the benchmark's random source."""


@dataclass(frozen=True)
class BenchConfig(Validated):
    """Sizes of an engine benchmark (the timings are its result; a scale changes only sizes)."""

    fast_episodes: int
    """Episodes per batch of the fast engine (the environment's training batch at every scale but
    smoke)."""
    reference_episodes: int
    """Episodes per batch of the SimPy reference."""
    repeats: int
    """Batches each engine runs per policy."""

    def validate(self) -> None:
        self.check(self.fast_episodes >= 1, "fast_episodes", "an integer >= 1")
        self.check(self.reference_episodes >= 1, "reference_episodes", "an integer >= 1")
        self.check(self.repeats >= 1, "repeats", "an integer >= 1")


def scales(env: str) -> dict[str, dict[str, int]]:
    """The ``SCALES`` of ``env``'s benchmark config, from its training batch (the reference's
    batches take seconds at the quick scale)."""
    batch = train_defaults(env_package(env))["batch_episodes"]
    return {
        "smoke": dict(fast_episodes=batch // 10, reference_episodes=2, repeats=1),
        "quick": dict(fast_episodes=batch, reference_episodes=batch // 20, repeats=5),
        "paper": dict(fast_episodes=batch, reference_episodes=batch // 10, repeats=15),
    }


class _Timed:
    """A policy that adds up the CPU time of its calls."""

    def __init__(self, policy: Policy):
        self.policy = policy
        self.cpu = 0.0

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        t0 = time.process_time()
        actions = self.policy(batch)
        self.cpu += time.process_time() - t0
        return actions


def _time(env: BatchEnv, policy: Policy, episodes: int, repeats: int, seed: int) -> dict:
    """A rollout of ``episodes`` per batch: totals over the batches, rates as medians."""
    return _timed_batches(lambda timed, child: env.rollout(timed, episodes, child).n_decisions,
                          policy, episodes, repeats, seed)


def _time_steps(env: BatchEnv, policy: Policy, episodes: int, repeats: int, seed: int,
                decisions: int) -> dict:
    """The step API on ``episodes`` envs per batch, stepped until it has made ``decisions``."""
    config = {f.name: getattr(env.cfg, f.name) for f in fields(env.cfg)}

    def steps(timed: _Timed, child: np.random.SeedSequence) -> int:
        vec = make_vector_env(env.name, episodes, child, **config)
        batch, made = vec.reset(), 0
        while made < decisions:
            made += len(batch)
            batch, _ = vec.step(timed(batch))
        return made

    return _timed_batches(steps, policy, episodes, repeats, seed)


def _timed_batches(run: Callable[[_Timed, np.random.SeedSequence], int], policy: Policy,
                   episodes: int, repeats: int, seed: int) -> dict:
    """``run(policy, child)`` for the seed's children; totals over them, rates as medians."""
    timed = _Timed(policy)
    batches = []
    for child in np.random.SeedSequence(seed).spawn(repeats):
        policy_cpu = timed.cpu
        cpu, wall = time.process_time(), time.perf_counter()
        n_decisions = run(timed, child)
        batches.append((n_decisions, time.perf_counter() - wall,
                        time.process_time() - cpu, timed.cpu - policy_cpu))
    d, wall, cpu, policy_cpu = np.array(batches).T
    return dict(batch_episodes=episodes, batches=repeats, episodes=episodes * repeats,
                decisions=int(d.sum()), wall_seconds=wall.sum(), cpu_seconds=cpu.sum(),
                policy_cpu_seconds=policy_cpu.sum(), decisions_per_second=np.median(d / wall),
                decisions_per_cpu_second=np.median(d / cpu),
                episodes_per_cpu_second=np.median(episodes / cpu),
                engine_decisions_per_cpu_second=np.median(d / (cpu - policy_cpu)))


def mlp_name(learner: str) -> str:
    """The benchmarks' name of a learner's fresh network: "authors-mlp-32-tanh"."""
    return f"{learner}-mlp-" + "x".join(map(str, LEARNERS[learner].hidden)) + "-tanh"


def _sampler(network: Any, normalizer: Any, env: BatchEnv, rng: np.random.Generator) -> Policy:
    """The trainer's sampler of ``network`` (a :data:`CheapPolicy`'s signature)."""
    from repro.learn.policy import Sampler

    return Sampler(network, normalizer, rng)


def measure(fast: BatchEnv, reference: BatchEnv, cheap_name: str, cheap: CheapPolicy,
            cfg: BenchConfig, seed: int, trained: dict[str, Any] | None = None) -> pd.DataFrame:
    """One row per engine and policy (see the module docstring); ``trained``: a loaded
    checkpoint (:func:`load_trained_run`) whose policy is timed instead of a fresh network.
    Batches that cannot fit in memory are refused first."""
    import torch  # here, not above: a command's options are checked without torch

    from repro.learn.policy import CategoricalPolicy, ObsNormalizer

    for env, episodes, param in ((fast, cfg.fast_episodes, "--fast-episodes"),
                                 (reference, cfg.reference_episodes, "--reference-episodes")):
        require_memory(rollout_bytes(env, episodes), param, episodes, "a batch of episodes")
    if trained is None:
        warm_up = fast.rollout(cheap(fast, np.random.default_rng(seed)), cfg.fast_episodes, seed)
        policies: dict[str, CheapPolicy] = {}
        for name, learner in LEARNERS.items():
            normalizer = ObsNormalizer(fast.obs_dim)
            if learner.normalize_obs:
                normalizer.update(warm_up.obs)
            torch.manual_seed(seed)
            network = CategoricalPolicy(fast.obs_dim, fast.n_actions, learner.hidden, learner.init)
            policies[mlp_name(name)] = partial(_sampler, network, normalizer)
        policies[cheap_name] = cheap
    else:
        check_fits(trained, fast, "--checkpoint", None)
        fast.rollout(cheap(fast, np.random.default_rng(seed)), 1, seed)  # compiles the engine
        policies = {"checkpoint": lambda env, rng: policy_from_state(trained, rng),
                    cheap_name: cheap}
    rows = []
    for engine, env, episodes in (("fast", fast, cfg.fast_episodes),
                                  ("reference", reference, cfg.reference_episodes)):
        for name, make in policies.items():
            policy = make(env, np.random.default_rng(seed))
            rows.append(dict(engine=engine, policy=name,
                             **_time(env, policy, episodes, cfg.repeats, seed)))
    # the step API on the fast engine with each policy, as many decisions per batch as the fast
    # engine's rollouts with that policy made
    for row, (name, make) in zip(rows[:len(policies)], policies.items()):
        rows.append(dict(engine="fast-step-api", policy=name,
                         **_time_steps(fast, make(fast, np.random.default_rng(seed)),
                                       cfg.fast_episodes, cfg.repeats, seed,
                                       row["decisions"] // cfg.repeats)))
    frame = pd.DataFrame(rows)
    ref = frame[frame.engine == "reference"].set_index("policy")
    for column, rate in (("speedup_vs_reference", "decisions_per_cpu_second"),
                         ("wall_speedup_vs_reference", "decisions_per_second"),
                         ("engine_speedup_vs_reference", "engine_decisions_per_cpu_second")):
        frame[column] = frame[rate] / frame.policy.map(ref[rate])
    return frame


VARIANTS = ("checkpoint",)
"""Options that choose the benchmark (``--checkpoint``: ``<command>_checkpoint.csv``), not its
settings (:func:`repro.studies.kit.options.scale_departures`)."""


def add_arguments(p: argparse.ArgumentParser, config: type[BenchConfig]) -> None:
    """A benchmark's options: its ``config``'s sizes (each flag's scale default is that class's)
    and ``--checkpoint``."""
    add_common(p, figures=False)
    add_config_arguments(p, config)
    p.add_argument("--checkpoint", help="time this training run's policy (its checkpoint.pt) "
                                        "instead of a fresh network, on that run's environment")


def configure(args: argparse.Namespace,
              config: type[BenchConfig]) -> Command[tuple[BenchConfig, str | None]]:
    """An engine benchmark's sizes (a ``config`` at the scale) and the training run whose
    checkpoint's network it times (``--checkpoint``; None: the engine's own network)."""
    return Command.of(args, (for_scale(config, args.scale, **given_fields(args, config)),
                             args.checkpoint))


def run(cmd: Command[tuple[BenchConfig, str | None]], folders: Folders, command: str,
        measure_env: Callable[[BenchConfig, int, dict[str, Any] | None], pd.DataFrame]) -> int:
    """The body of a benchmark command: checks, timing, the CSV ``<command>.csv``
    (``<command>_checkpoint.csv`` with ``--checkpoint``)."""
    (cfg, checkpoint), seed = cmd.study, cmd.seed
    trained = (None if checkpoint is None
               else load_trained_run(checkpoint, command.removeprefix("bench-")))
    results = folders.open_results()
    load_before = os.getloadavg()[0]
    t0 = time.perf_counter()
    frame = measure_env(cfg, seed, trained)
    prov = provenance(cfg, command=command, scale=folders.scale, seed=seed,
                      wall_seconds=time.perf_counter() - t0,
                      extra={"note": "timings vary between runs and machines; one thread",
                             "load_average_1min": [load_before, os.getloadavg()[0]],
                             "checkpoint": checkpoint})
    stem = command.replace("-", "_") + ("" if checkpoint is None else "_checkpoint")
    write_result(results / f"{stem}.csv", frame, prov)
    print(frame.to_string(index=False))
    return 0
