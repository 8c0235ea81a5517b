"""Parameters of the wildfire environment (docs/semantics.md section 3) and the fire layout."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from repro.core.config import Validated
from repro.core.errors import require
from repro.core.event_queue import MAX_WHO
from repro.core.rollout import children

# The observation's layout, named once (the engines write it in this order; heuristics, wrappers
# and drivers read it through these names).
OWN_X, OWN_Y = 0, 1
"""Columns of the UAV's own position."""
FIRES = 2
"""First column of the fires' blocks: one per observed fire, closest first."""
DIST, LEVEL, INTEREST, STATUS, HEALTH = range(5)
"""Offsets within a fire's block: distance, level, interest party size, status (1 alive),
remaining health."""
OBS_PER_FIRE = 5
"""Columns per fire."""
SOJOURN = -1
"""The last column: time since the current action started."""


def fire_blocks(obs: np.ndarray, n_observed: int) -> np.ndarray:
    """(M, n_observed, OBS_PER_FIRE) view of the fires' blocks of (M, obs_dim) observations."""
    return obs[:, FIRES:FIRES + OBS_PER_FIRE * n_observed].reshape(len(obs), n_observed,
                                                                   OBS_PER_FIRE)
SAME_INSTANT_ORDERS = ("released", "scheduling")
"""Values of :attr:`WildfireConfig.same_instant_order`."""


RACE_TOLERANCE = 1e-9
"""Expiry times, and exact due times, closer than this (s) count as one in the race count
(docs/semantics.md section 3.12): two events on one grid point can differ in the last bit, and
two flights of equal length (in clusters rotated onto each other) in the last bits."""


MAX_T_MAX = 1e5
"""The longest episode cap T_max (s) a config may ask for (through a small gamma)."""


SIM_VERSIONS: dict[str, dict[str, float]] = {
    "2017-05-16": dict(r_pen=-20.0),
    "2017-04-22": dict(r_pen=-1.0),
}
"""The released simulator's versions the paper's figures were drawn with, by commit date, as the
settings in which they differ (the crowding penalty is their only difference in simulation):
"2017-05-16" is the released HEAD (d05757b, which adds the transfer figure's script);
"2017-04-22" is b3bef87, four minutes before the transfer study's training runs started (their
folders, dated 2017-04-22 18:17-19:15, are listed in cluster_fire_smdp.py's evaluation block).
docs/semantics.md section 3.13 gives the evidence."""
RELEASED_VERSION, FIGURE_VERSION = "2017-05-16", "2017-04-22"
"""The released HEAD (the default everywhere), and the version the transfer figure was drawn
with."""


def version_suffix(version: str) -> tuple[str, ...]:
    """The part of a result's file stem that names a simulator version other than the released
    HEAD: ``("20170422",)``, or nothing."""
    return () if version == RELEASED_VERSION else (version.replace("-", ""),)


@dataclass(frozen=True)
class WildfireConfig(Validated):
    """Every parameter of docs/semantics.md section 3.1 and every switch of section 3.11; the
    defaults are the paper's (released implementation)."""

    n_agents: int = 3
    """N, the number of UAVs."""
    v_uav: float = 0.015
    """UAV speed (m/s)."""
    hold_mean: float = 3.0
    """Mean of the Normal hold duration (s)."""
    hold_std: float = 0.3
    """Standard deviation of the Normal hold duration (s); a negative draw is treated as 0."""
    t_health: float = 3.0
    """UAV-seconds a fire's extinguish party must spend on it to put it out."""
    r_ext: float = 1.0
    """Reward every agent accrues when any fire is extinguished."""
    r_pen: float = -20.0
    """Reward accrued when a UAV joins an extinguish party that already has a member: -20 in the
    paper's table and the released simulator (2017-05-16), -1 in the simulator the transfer runs
    were trained on (2017-04-22; :data:`SIM_VERSIONS`)."""
    gamma: float = 0.02
    """Continuous-time discount rate (1/s)."""
    horizon_discount: float = 0.005
    """The episode is cut at T_max = ln(horizon_discount) / (-gamma) (264.9 s with the defaults)."""
    decision_latency: float = 1e-5
    """Time between an observation and the action it leads to (s); never rounded to the grid."""
    at_fire_tol: float = 1e-3
    """The simulator's "at a fire" distance (m; the released code's): a hold joins the parties of
    the first fire (by index) closer than this, and Q6 uses it too. Observers of decisions use a
    looser one, ``policies.OBSERVED_AT_FIRE_TOL``, which says why."""
    n_observed: int = 5
    """Fires in an observation (the closest ones) and fly actions (one per observed fire)."""
    cluster_radius: float = 1.0
    """Distance from the origin of the two outer fires' midpoint in each cluster (m)."""
    fire_spacing: float = 0.02
    """Side of the equilateral triangle each cluster of three fires forms (m)."""
    n_clusters: int = 3
    """Clusters of three fires: cluster A, then A rotated about the origin by 360/n_clusters deg,
    twice that, and so on (:func:`fire_positions`). 3 is the paper's layout of 9 fires; more
    clusters keep the fires per UAV of the paper when N grows (the race study X2 runs
    n_clusters = N)."""
    dt: float | None = None
    """Fixed step dT of the FS simulator (s); None is the event-driven (ED) simulator."""
    quirk_q1_stale_attack: bool = True
    """Q1: after a fly action the UAV still remembers the fire it attacked, so holding at it again
    rejoins nothing until it attacks another fire (released implementation; False = paper)."""
    quirk_q2_penalty_party_only: bool = True
    """Q2: r_pen goes to the extinguish party's members only (released implementation); False gives
    it to every agent, as the paper says."""
    quirk_q3_unclamped_health: bool = True
    """Q3: a fire's observed remaining health is ``health - party size * time since the party last
    changed``, unclamped, also once the fire is out (released implementation): it goes negative
    in FS when the rounded extinguish event comes after the health ran out, and a fire that is out
    keeps draining at the rate of the party it had (nobody leaves the party of a fire that is out).
    False: clamped at 0, and 0 for fires that are out."""
    quirk_q4_latency_not_interrupted: bool = True
    """Q4: a fire going out while a UAV interested in it waits its decision latency does not
    interrupt it (released implementation: the interrupt reaches the UAV's previous, finished
    action and is swallowed): the UAV carries out the decision made on its stale observation.
    False: the pending decision is dropped and the UAV decides again at once."""
    quirk_q5_discount_from_action_start: bool = True
    """Q5: a UAV's rewards are discounted from the start of its latest action, as the released
    implementation does, not from its latest observation. Besides shifting every weight by
    ``exp(gamma * latency)`` (below 1e-6), a reward accrued while the UAV waits its decision
    latency (in FS: a fire out, or a penalty, at the grid instant it observed) belongs to the new
    decision but is discounted from the PREVIOUS action's start. False: from the observation."""
    fs_round_negative_delays: bool = True
    """In FS a fire's health can run out before its rounded extinguish event; a party change in
    between re-plans it with a negative delay, which is rounded to the grid like any other delay
    (docs/semantics.md section 2.3, released code): the fire goes out at once if a grid point lies
    between the run-out and now. False: the negative delay counts as 0, so the fire goes out at
    the next grid point."""
    cut_flight_continues: bool = True
    """A flight cut by its fire going out goes on along its segment until the UAV's next action
    starts, one decision latency later (released code: the position is computed from the
    action's start, and only the next action sets a new start). The UAV observes where it is at
    the cut; the 1.5e-7 m it flies during the latency can move the next flight's rounded FS
    arrival by a grid step. False: it stops where it is at the cut."""
    ranking_resolution: float = 1e-9
    """Fires are ranked by distance rounded to multiples of this (m), ties to the lower fire index:
    a UAV at a fire sees its two cluster-mates, and its 5th and 6th closest fires (other
    clusters), at equal distances up to round-off, and this ranks them by index, whatever the
    round-off. A deliberate deviation: the released code ranks
    them by floating-point noise. 0: exact distances (the noise decides)."""
    quirk_q6_short_flight_stays: bool = True
    """Q6: a flight shorter than ``at_fire_tol`` takes its travel time but leaves the UAV where it
    was (released implementation: its position is the action's start while that is within 1e-3 m
    of the goal). E.g. a UAV cut 0.7 mm after leaving a fire, that flies back to it, stays 0.7 mm
    off (close enough to hold there). False: it lands at the goal."""
    same_instant_order: str = "released"
    """Order of events at one instant. "released": the order of the released implementation's
    process structure (a macro-action's end reaches its UAV through its action process and an
    AnyOf condition; a fire burns in a sub-process that party changes interrupt; the episode ends
    through the conditions "all fires out" or T_max; a fire interrupts the UAVs interested in it in
    the order they joined its interest party). "scheduling": each process waits on its own timeouts
    and the episode ends at once (the order of runs recorded before this setting existed). Not a
    quirk: the corrected semantics keep "released"."""
    fire_out_first: bool = True
    """Released order: at one instant, a fire's extinguishing comes before the observation of a UAV
    whose macro-action ends then (its extinguish timeout reaches it one event later, a
    macro-action's end reaches its UAV two later; docs/semantics.md section 3.9), so the UAV sees
    the fire out and its r_ext belongs to the macro-action that ended. False reverses the two
    (claim X4): the fire goes out two zero-delay events later still (SimPy: two ``timeout(0)``),
    after such UAVs observed: they see it alive, and it goes out in their decision latency (Q4
    decides whether that interrupts them). Only in the "released" same-instant order."""
    max_decisions: int | None = 1000
    """The episode also ends when a UAV's macro-action ends after its ``max_decisions``-th decision
    (instead of that UAV deciding again), as at T_max: every running macro-action is cut, and the
    episode is reported truncated (``Rollout.truncated``; the trainer's ``truncated_episodes``).
    None: no limit, the released simulator (docs/semantics.md section 3.7). Not in the paper: it
    bounds every episode, and so the memory of a batch, for any policy. Only a policy that flies
    to the fire it is at, over and over, comes near it: each such flight takes no time, so the UAV
    decides again after the latency, up to T_max / 1e-5 s = 26 million times an episode; without
    such *stay flights* a UAV's shortest moves, between fires of a cluster, take 1.3 s, so it
    decides at most about 200 times in T_max."""
    hold_table_size: int = 128
    """Hold durations pre-drawn per agent and episode, at least: :attr:`hold_table` adds more when
    T_max needs them. Used in order, cyclically; both engines index the table by the agent's hold
    count."""

    BEFORE_ADDED: ClassVar[dict[str, object]] = dict(
        quirk_q3_unclamped_health=False, quirk_q4_latency_not_interrupted=False,
        quirk_q5_discount_from_action_start=False, quirk_q6_short_flight_stays=False,
        fs_round_negative_delays=False, cut_flight_continues=False, ranking_resolution=0.0,
        same_instant_order="scheduling", max_decisions=None)
    """What runs recorded before these settings existed ran: not the released simulator's
    semantics (so that such a run is not resumed as one of them), and no decision limit."""

    @classmethod
    def corrected(cls, **fields) -> WildfireConfig:
        """The paper's prose: quirks Q1-Q6 all off (``--corrected``; the released same-instant
        order stays), other fields as given."""
        return cls(**{**dict.fromkeys(QUIRKS, False), **fields})

    ALIASES: ClassVar[dict[str, str]] = {
        "quirk_q1": "quirk_q1_stale_attack", "quirk_q2": "quirk_q2_penalty_party_only",
        "quirk_q3": "quirk_q3_unclamped_health", "quirk_q4": "quirk_q4_latency_not_interrupted",
        "quirk_q5": "quirk_q5_discount_from_action_start",
        "quirk_q6": "quirk_q6_short_flight_stays"}
    """Older flags of the quirks (``--quirk-q3``, ``--no-quirk-q3``), still taken."""

    def validate(self) -> None:
        # the fast engine's event keys hold an agent index up to MAX_WHO = 2^20 - 1
        self.check(isinstance(self.n_agents, numbers.Integral) and 1 <= self.n_agents <= MAX_WHO,
                   "n_agents", "an integer from 1 to 2^20 - 1")
        self.check(self.t_health > 0 and math.isfinite(self.t_health), "t_health", "a number > 0")
        self.check(self.dt is None or (self.dt > 0 and math.isfinite(self.dt)), "dt",
                   "a number > 0")
        self.check(self.v_uav > 0 and math.isfinite(self.v_uav), "v_uav", "a number > 0")
        self.check(0 < self.horizon_discount < 1, "horizon_discount", "in (0, 1)")
        # T_max sets the hold table, drawn for a whole batch up front: 1e5 s is 48,000 holds per
        # UAV and episode (the paper's T_max is 265 s)
        least = math.log(1.0 / self.horizon_discount) / MAX_T_MAX
        self.check(least <= self.gamma < math.inf, "gamma", f"a number >= {least:.3g} (the "
                   f"episode cap T_max = ln(1/{self.horizon_discount:g}) / gamma is at most "
                   f"{MAX_T_MAX:g} s)")
        self.check(self.dt is None or self.dt <= self.t_max, "dt",
                   f"at most the episode cap T_max = {self.t_max:.4g} s")
        # with no latency a UAV flying to the fire it is at would decide forever at one instant
        self.check(self.decision_latency > 0 and math.isfinite(self.decision_latency),
                   "decision_latency", "a number > 0")
        self.check(self.hold_mean > 0 and math.isfinite(self.hold_mean), "hold_mean",
                   "a number > 0")
        self.check(self.hold_std >= 0 and math.isfinite(self.hold_std), "hold_std",
                   "a number >= 0")
        # a fire's index is a heap key's subject, like an agent's
        self.check(isinstance(self.n_clusters, numbers.Integral) and 1 <= self.n_clusters < 2**18,
                   "n_clusters", "an integer from 1 to 2^18 - 1")
        self.check(1 <= self.n_observed <= self.n_fires, "n_observed",
                   f"between 1 and the number of fires ({self.n_fires})")
        self.check(self.ranking_resolution >= 0 and math.isfinite(self.ranking_resolution),
                   "ranking_resolution", "a number >= 0")
        self.check(self.same_instant_order in SAME_INSTANT_ORDERS, "same_instant_order",
                   " or ".join(SAME_INSTANT_ORDERS))
        require(self.fire_out_first or self.same_instant_order == "released",
                "--no-fire-out-first", "used with --same-instant-order released")
        self.check(self.max_decisions is None or self.max_decisions >= 1, "max_decisions",
                   "a positive integer, or none (0: none, on the command line)")
        self.check(self.hold_table_size >= 1, "hold_table_size", "an integer >= 1")

    @property
    def t_max(self) -> float:
        """Episode length cap T_max (s)."""
        return math.log(self.horizon_discount) / (-self.gamma)

    @property
    def hold_table(self) -> int:
        """Holds drawn per agent and episode: ``hold_table_size``, or as many as a UAV that only
        holds could make within T_max, each hold three standard deviations short, if that is more.
        With the defaults that is 127, so the table stays at 128; with gamma = 0.005 (T_max 1060 s)
        it is 505, where a table of 128 would repeat its durations after 128 holds."""
        shortest = self.hold_mean - 3.0 * self.hold_std
        need = math.ceil(self.t_max / shortest) if shortest > 0 else 0
        return max(self.hold_table_size, need)

    @property
    def n_fires(self) -> int:
        """Three per cluster."""
        return 3 * self.n_clusters

    @property
    def n_actions(self) -> int:
        """Fly to each observed fire, or hold."""
        return self.n_observed + 1

    @property
    def obs_dim(self) -> int:
        """Own x, y; OBS_PER_FIRE values per observed fire; sojourn time."""
        return 2 + OBS_PER_FIRE * self.n_observed + 1

    @property
    def label(self) -> str:
        """ED, or FS-dT."""
        return "ED" if self.dt is None else f"FS-{self.dt:g}"


QUIRKS = tuple(f for f in WildfireConfig.__dataclass_fields__ if f.startswith("quirk_"))
"""The released implementation's quirks Q1-Q6: all on by default, all off in the corrected
semantics (the paper's prose). The same-instant order, the FS rounding of negative delays and
cut flights going on stay as released; they are not quirks."""


def fire_positions(cfg: WildfireConfig = WildfireConfig()) -> np.ndarray:
    """(n_fires, 2) fire locations: cluster A, then A rotated about the origin by k 360/n_clusters
    deg for k = 1, ..., n_clusters - 1 (the paper's three: A, B at +120 deg, C at -120 deg).

    Cluster A is (-s/2, R), (s/2, R), (0, R - s sin 60deg) with s = fire_spacing,
    R = cluster_radius.
    """
    s, r = cfg.fire_spacing, cfg.cluster_radius
    a = np.array([[-s / 2, r], [s / 2, r], [0.0, r - s * math.sin(math.radians(60))]])
    out = [a]
    for k in range(1, cfg.n_clusters):
        deg = 360.0 * k / cfg.n_clusters
        # angles in (-180, 180]: 240 deg as -120, whose sine and cosine give the paper's layout
        # bit for bit (those of 240 differ in the last bit)
        deg = deg - 360.0 if deg > 180.0 else deg
        c, sn = math.cos(math.radians(deg)), math.sin(math.radians(deg))
        out.append(a @ np.array([[c, sn], [-sn, c]]))
    return np.concatenate(out)


def rank_key(distance: float, resolution: float) -> float:
    """What fires are ranked by (ties to the lower index): the distance rounded to multiples of
    ``resolution``, or the distance itself if ``resolution`` is 0. Plain float arithmetic, so the
    numba engine compiles the same operations."""
    if resolution <= 0.0:
        return distance
    return np.floor(distance / resolution + 0.5)


@dataclass(frozen=True)
class EpisodeDraws:
    """All the randomness of a batch of episodes, drawn before simulating (engine-independent)."""

    starts: np.ndarray
    """(E, N, 2) UAV start positions."""
    holds: np.ndarray
    """(E, N, cfg.hold_table) hold durations; agent i's h-th hold lasts holds[e, i, h % size]."""

    @property
    def n_episodes(self) -> int:
        return len(self.starts)


def draw_episodes(cfg: WildfireConfig, n_episodes: int,
                  seed: int | np.random.SeedSequence) -> EpisodeDraws:
    """The randomness of a batch of episodes in two vectorised draws (both engines use this):
    the first ``n_episodes`` of the seed's :class:`EpisodeStream`."""
    return EpisodeStream(cfg, seed).draw(n_episodes)


class EpisodeStream:
    """The seed's episodes, drawn in batches in order.

    The seed's two spawned children drive one generator each: start positions (uniform on
    [-1, 1]^2) and hold durations (Normal). Each fills its array episode by episode, value by
    value, so the draws of episode e do not depend on how the episodes before it were batched: a
    batch of ``draw_episodes`` is a prefix of any larger one of the same seed, and the vector env
    (``draw`` again and again) meets the same episodes. One generator per stream, not per
    episode: creating a generator costs more than simulating a short episode. The holds are
    numpy's ``normal(hold_mean, hold_std, size)``, drawn by :func:`normal_fill`.
    """

    def __init__(self, cfg: WildfireConfig, seed: int | np.random.SeedSequence):
        self.cfg = cfg
        self._starts, self._holds = (np.random.default_rng(ss) for ss in children(seed, 2))

    def draw(self, n_episodes: int) -> EpisodeDraws:
        """The stream's next ``n_episodes`` episodes."""
        cfg = self.cfg
        starts = self._starts.uniform(-1.0, 1.0, size=(n_episodes, cfg.n_agents, 2))
        holds = np.empty((n_episodes, cfg.n_agents, cfg.hold_table))
        normal_fill(self._holds, cfg.hold_mean, cfg.hold_std, holds.reshape(-1))
        return EpisodeDraws(starts, holds)


@njit(cache=True)
def normal_fill(rng, mean, std, out):
    """Fill ``out`` (1-d) in order with the values of ``rng.normal(mean, std, out.size)``, leaving
    ``rng`` in the state that call would: numba draws numpy's ziggurat with its tables and in its
    operations (and ``mean + std z`` as numpy's ``normal`` computes it), at about a third of
    numpy's cost per value, which matters here: an episode draws 128 holds per UAV, and a random
    policy's episode makes about 24 decisions. A test compares the two, the ziggurat's tail
    included."""
    for i in range(out.shape[0]):
        out[i] = mean + std * rng.standard_normal()


def stream_draws(cfg: WildfireConfig) -> int:
    """Uniforms an episode takes from a shared random stream (:func:`draws_from_uniforms`): two
    per UAV for its start, one per hold of its table."""
    return cfg.n_agents * (2 + cfg.hold_table)


LOWEST_UNIFORM = 2.0 ** -54
"""What a uniform of 0 (a generator's ``random()`` gives it with probability 2^-53) counts as in
the inverse normal CDF, which is -inf at 0: half the generator's step, a hold 8.3 standard
deviations short (the largest uniform, 1 - 2^-53, gives 8.2 long)."""


def draws_from_uniforms(cfg: WildfireConfig, uniforms: np.ndarray) -> EpisodeDraws:
    """The draws of episodes taken from a shared random stream (the released pool,
    :mod:`repro.learn.pool`): row e of the (E, :func:`stream_draws`) ``uniforms`` on [0, 1) is
    episode e's, in this order: every UAV's start (x, y; UAV 0 first) as ``-1 + 2 u``, then every
    UAV's hold table (UAV 0's first) by the inverse normal CDF, ``hold_mean + hold_std
    ndtri(u)``. One uniform per value, whatever the values, so that an episode takes a fixed
    stretch of the stream."""
    from scipy.special import ndtri

    u = np.asarray(uniforms, np.float64)
    n, table = cfg.n_agents, cfg.hold_table
    if u.ndim != 2 or u.shape[1] != stream_draws(cfg):
        raise ValueError(f"uniforms must have shape (episodes, {stream_draws(cfg)}), "
                         f"got {u.shape}")
    starts = -1.0 + 2.0 * u[:, :2 * n].reshape(len(u), n, 2)
    normal = ndtri(np.maximum(u[:, 2 * n:], LOWEST_UNIFORM)).reshape(len(u), n, table)
    return EpisodeDraws(starts, cfg.hold_mean + cfg.hold_std * normal)


class RunsOnStream:
    """Mixin of both wildfire engines: the environment's side of the released pool
    (:class:`repro.core.rollout.RunsOnDraws`), episodes run on draws taken from a shared
    stream."""

    cfg: WildfireConfig

    @property
    def draws_per_episode(self) -> int:
        return stream_draws(self.cfg)

    def episode_draws(self, uniforms: np.ndarray) -> EpisodeDraws:
        return draws_from_uniforms(self.cfg, uniforms)
