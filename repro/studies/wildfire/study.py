"""What the wildfire studies share: the evaluation every study that tests a wildfire policy runs
(the ADR of a policy over many episodes, simulated in batches), and the behaviour study's sizes
and classification of decisions (C6; :mod:`repro.studies.wildfire.behaviour` defines them), which
the study over crowding penalties (:mod:`repro.studies.wildfire.penalty`) reuses."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, ClassVar

import numpy as np

from repro.core.config import for_scale, given_fields
from repro.core.rollout import Policy, Rollout, concat, rollout_bytes
from repro.envs.wildfire import (RELEASED_VERSION, SIM_VERSIONS, WildfireConfig, fire_positions,
                                 version_suffix)
from repro.envs.wildfire.params import DIST, INTEREST, OWN_X, OWN_Y, STATUS, fire_blocks
from repro.envs.wildfire.policies import OBSERVED_AT_FIRE_TOL
from repro.learn.config import learner_suffix
from repro.runs.memory import require_memory
from repro.runs.stats import sem
from repro.studies.kit.training import StudyTraining


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


def counted(env, policy: Policy, n_episodes: int, seed: int,
            count: Callable[[Rollout], dict[str, int]]) -> tuple[dict[str, int], Rollout]:
    """``count``'s counts summed over ``n_episodes`` test episodes of ``policy`` (observations not
    kept), and the rollout."""
    parts: list[dict[str, int]] = []
    rollout = evaluate(env, policy, n_episodes, seed, keep_obs=False,
                       on_batch=lambda batch: parts.append(count(batch)))
    return {key: sum(p[key] for p in parts) for key in parts[0]}, rollout


FIRES_PER_CLUSTER = 3


@dataclass(frozen=True)
class BehaviourConfig(StudyTraining):
    """Sizes of the behaviour study (the ED simulator and its semantics never change). How each
    policy trains: :class:`~repro.studies.kit.training.StudyTraining`."""

    seeds: int = 1
    """Policies trained from scratch (the paper examined one). Long ED runs can drift into
    policies that re-decide at a fire many times per second (fly to the fire they are at), which
    makes their epochs up to ten times slower; hence one at quick scale."""
    epochs: int = 300
    """Training epochs per policy (paper: 3,000)."""
    batch_episodes: int = 200
    sim_version: str = RELEASED_VERSION
    """The released simulator's version (``repro.envs.wildfire.SIM_VERSIONS``)."""
    test_episodes: int = 1000
    """ED episodes on which frequencies and ADRs are measured."""
    max_decisions: int | None = WildfireConfig.max_decisions
    """Decision limit per UAV and episode in training and test (``WildfireConfig.max_decisions``);
    None: no limit (docs/semantics.md section 3.7). Long ED runs drift into stay flights: without
    the limit a 600-episode epoch of them needed more than 14.7 million decisions and ran out of
    24 GB of memory at epoch 302 of a paper-scale run."""

    SCALES: ClassVar[dict] = {
        "smoke": dict(seeds=1, epochs=2, batch_episodes=8, batch_decisions=300, test_episodes=20),
        "quick": {},
        "paper": dict(seeds=3, epochs=3000, batch_episodes=600, batch_decisions=12000,
                      test_episodes=10000),
    }

    def validate(self) -> None:
        super().validate()
        self.check(self.test_episodes >= 1, "test_episodes", "an integer >= 1")
        self.check(self.sim_version in SIM_VERSIONS, "sim_version",
                   "one of " + ", ".join(SIM_VERSIONS))
        self.check(self.max_decisions is None or self.max_decisions >= 1, "max_decisions",
                   "a positive integer (0: no limit)")

    def env(self) -> WildfireConfig:
        """The ED simulator every policy is trained and tested on."""
        return WildfireConfig(max_decisions=self.max_decisions, **SIM_VERSIONS[self.sim_version])

    @property
    def name(self) -> str:
        """File stem: wildfire_behaviour, then _suite for the suite's learner and _20170422 for
        the simulator of 2017-04-22."""
        return "_".join(("wildfire_behaviour", *learner_suffix(self.learner),
                         *version_suffix(self.sim_version)))


STAY = "_ex_stay"
"""Suffix of the frequencies counted without stay flights (see the module docstring)."""


def frequency_counts(rollout: Rollout, env: WildfireConfig) -> dict[str, int]:
    """The counts behind the C6 frequencies: for each, the decisions where its event happened
    (``<name>_events``) out of those where its condition held (``n_shared``, ``n_alone``,
    ``n_fly``); the same without stay flights (suffix ``_ex_stay``); and the stay flights
    (``stay_flight_events`` of ``n_decisions``). Counts of separate batches add up."""
    obs, act, k = rollout.obs, rollout.actions, env.n_observed
    block = fire_blocks(obs, k)
    rows = np.arange(len(obs))
    at_live = (block[:, 0, DIST] < OBSERVED_AT_FIRE_TOL) & (block[:, 0, STATUS] > 0.5)
    shared = block[:, 0, INTEREST] - 1 >= 1
    hold = act == k
    fly = ~hold
    stay = fly & (block[rows, np.minimum(act, k - 1), DIST] < OBSERVED_AT_FIRE_TOL)
    dist = np.linalg.norm(obs[:, None, OWN_X:OWN_Y + 1] - fire_positions(env)[None], axis=2)
    order = np.argsort(dist, axis=1, kind="stable")
    target_cluster = order[rows, np.minimum(act, k - 1)] // FIRES_PER_CLUSTER
    closest = target_cluster == order[:, 0] // FIRES_PER_CLUSTER

    def counts(keep: np.ndarray, suffix: str) -> dict[str, int]:
        out = dict(hold_shared_events=hold & at_live & shared,
                   hold_alone_events=hold & at_live & ~shared)
        out.update({f"fly_rank_{r + 1}_events": act == r for r in range(k)})
        out.update(closest_cluster_events=closest & fly, n_shared=at_live & shared,
                   n_alone=at_live & ~shared, n_fly=fly)
        return {name + suffix: int((mask & keep).sum()) for name, mask in out.items()}

    everything = np.ones(len(act), bool)
    return {**counts(everything, ""), **counts(~stay, STAY),
            "stay_flight_events": int(stay.sum()), "n_decisions": len(act)}


def shares(counts: dict[str, int]) -> dict[str, float]:
    """The C6 frequencies of the module docstring from :func:`frequency_counts` (NaN where a
    condition never occurs), with the number of decisions behind each conditional."""
    given = dict(hold_shared="n_shared", hold_alone="n_alone", stay_flight="n_decisions")
    out = {}
    for key in counts:
        if key.endswith("_events") or key.endswith("_events" + STAY):
            name, suffix = key.split("_events")
            n = counts[given.get(name, "n_fly") + suffix]
            out[name + suffix] = counts[key] / n if n else float("nan")
    out.update({k: v for k, v in counts.items() if k.startswith("n_")})
    return out


def frequencies(rollout: Rollout, env: WildfireConfig) -> dict[str, float]:
    """The C6 frequencies of one rollout (see :func:`shares`)."""
    return shares(frequency_counts(rollout, env))


def behaviour_config(cls: type, args) -> BehaviourConfig:
    """The validated ``cls`` (:class:`BehaviourConfig` or a study extending it) of a command line
    at its scale (UsageError if bad); ``--max-decisions 0``: no limit."""
    given = given_fields(args, cls)
    no_limit = "max_decisions" in given and not given["max_decisions"]
    if no_limit:
        del given["max_decisions"]  # for_scale takes None as "not given"
    cfg = for_scale(cls, args.scale, **given)
    return replace(cfg, max_decisions=None) if no_limit else cfg
