"""The wildfire environment of SPEC section 3 as a SimPy model: the oracle the fast engine must
match.

One process per UAV and one per fire, as the paper describes event-driven simulation:

- A UAV observes, waits the decision latency, acts, and waits for its macro-action to end. A fire
  it is interested in being extinguished interrupts that wait (the latency included: an action
  not yet started is then dropped) and the UAV decides again.
- A fire waits until its extinguish party has spent its remaining health. Every party change
  drains the health at the old rate and interrupts the fire, which re-plans its extinguish time
  (in FS, re-rounds it to the grid).

Choices the SPEC leaves open, made once here and mirrored by the fast engine:

- A decision's macro-action starts at its observation (the latency belongs to it), so the
  durations of a path add up to the episode's end time.
- Observed remaining health is ``max(0, ...)`` for live fires (in FS the rounded extinguish event
  can come after the health ran out) and 0 for fires that are out.
- Parties are sets of agent indices; interrupts and penalties go out in agent-index order. A fire
  that is out keeps its interest party (UAVs leave it with their next action), and joining or
  leaving its extinguish party does nothing (but Q1's memory of the attacked fire is still set).
- The episode ends right after the event that puts out the last fire or reaches T_max, or (with
  ``max_decisions``) ends a UAV's macro-action after its last allowed decision; events scheduled
  for the same instant are not processed.
"""

from __future__ import annotations

import math

import numpy as np
import simpy

from repro.core.rollout import DecisionBatch, Policy, Rollout
from repro.envs.wildfire.params import (EpisodeDraws, WildfireConfig, draw_episodes,
                                        fire_positions, fs_delay)
from repro.envs.wildfire.records import rollout_from_records

class WildfireModel:
    """One episode. Drive it with :meth:`advance` and :meth:`act` (or let :class:`ReferenceEnv`)."""

    def __init__(self, cfg: WildfireConfig, starts: np.ndarray, holds: np.ndarray):
        self.cfg = cfg
        self.fires = fire_positions(cfg)
        n, k = cfg.n_agents, len(self.fires)
        self.dt = cfg.dt or 0.0
        self.holds = holds
        self.env = simpy.Environment()
        # UAV state
        self.pos = [tuple(p) for p in starts]
        self.flight: list[tuple | None] = [None] * n  # (origin, goal, departure time, length)
        self.interest = [-1] * n  # fire whose interest party the UAV is in
        self.attacking = [-1] * n  # fire the UAV remembers attacking (quirk Q1)
        self.in_party = [False] * n  # whether it is in that fire's extinguish party
        self.n_holds = [0] * n
        self.action: list[int | None] = [None] * n
        self.ranking: list[list[int]] = [[] for _ in range(n)]
        # fire state
        self.alive = [True] * k
        self.health = [cfg.t_health] * k  # as of t_update
        self.t_update = [0.0] * k
        self.party = [0] * k  # extinguish party size
        # records: one list entry per decision
        self.rec: list[dict] = []
        self.current = [-1] * n  # each UAV's current decision (index into rec)
        self.returns = np.zeros(n)
        self.pending: list[int] = []  # UAVs that observed and wait for their action
        self.done = False
        self.t_end = math.nan
        self.events = 0
        self.fire_procs = [self.env.process(self._fire(j)) for j in range(k)]
        self.uav_procs = [self.env.process(self._uav(i)) for i in range(n)]
        self.env.process(self._clock())

    # --- driving ---------------------------------------------------------------------------------

    def advance(self) -> None:
        """Process events until a UAV waits for its action or the episode is over."""
        while not self.pending and not self.done:
            self.env.step()
            self.events += 1

    def act(self, i: int, action: int) -> None:
        """Pending UAV ``i`` takes ``action``: 0..n_observed-1 fly to the k-th closest, or hold."""
        self.pending.remove(i)
        self.action[i] = int(action)
        self.rec[self.current[i]]["action"] = int(action)

    # --- processes -------------------------------------------------------------------------------

    def _uav(self, i: int):
        while True:
            if self._decisions(i) == self.cfg.max_decisions:
                self._end()
                return
            self._observe(i)
            try:
                yield self.env.timeout(self.cfg.decision_latency)
                yield self.env.timeout(self._start_action(i))
                self._land(i, cut=False)
            except simpy.Interrupt:
                self._land(i, cut=True)

    def _fire(self, j: int):
        while True:
            try:
                if self.party[j] == 0:
                    yield self.env.event()  # idle until the party changes
                else:
                    yield self.env.timeout(self._delay(self.health[j] / self.party[j]))
                    break
            except simpy.Interrupt:
                pass  # the party changed: re-plan
        self._extinguish(j)

    def _clock(self):
        yield self.env.timeout(self.cfg.t_max)
        self._end()

    # --- UAV -------------------------------------------------------------------------------------

    def _observe(self, i: int) -> None:
        now, cfg = self.env.now, self.cfg
        prev = self.current[i]
        sojourn = 0.0 if prev < 0 else now - self.rec[prev]["time"]
        if prev >= 0:
            self.rec[prev]["duration"] = sojourn
        x, y = self.pos[i]
        dist = np.array([math.sqrt((fx - x) * (fx - x) + (fy - y) * (fy - y))
                         for fx, fy in self.fires])
        rank = np.argsort(dist, kind="stable")[:cfg.n_observed]
        self.ranking[i] = rank.tolist()
        obs = [x, y]
        for j in rank:
            interested = sum(1 for f in self.interest if f == j)
            obs += [dist[j], 1.0, float(interested), float(self.alive[j]), self._health_now(j)]
        obs.append(sojourn)
        self.current[i] = len(self.rec)
        self.rec.append(dict(agent=i, prev=prev,
                             index=0 if prev < 0 else self.rec[prev]["index"] + 1,
                             time=now, obs=obs, action=-1, reward=0.0, duration=math.nan))
        self.pending.append(i)

    def _start_action(self, i: int) -> float:
        """Act; return the macro-action's (rounded) duration."""
        cfg, now = self.cfg, self.env.now
        self.interest[i] = -1
        a = self.action[i]
        if a < cfg.n_observed:
            target = self.ranking[i][a]
            self.interest[i] = target
            if self.in_party[i]:
                self.in_party[i] = False
                self._party_change(self.attacking[i], -1)
            if not cfg.quirk_q1_stale_attack:
                self.attacking[i] = -1
            origin, goal = self.pos[i], tuple(self.fires[target])
            length = math.sqrt((goal[0] - origin[0]) * (goal[0] - origin[0])
                               + (goal[1] - origin[1]) * (goal[1] - origin[1]))
            self.flight[i] = (origin, goal, now, length)
            return self._delay(length / cfg.v_uav)
        x, y = self.pos[i]
        for j, (fx, fy) in enumerate(self.fires):
            if math.sqrt((fx - x) * (fx - x) + (fy - y) * (fy - y)) < cfg.at_fire_tol:
                self.interest[i] = j
                if self.attacking[i] != j:
                    self.attacking[i] = j
                    if self.alive[j]:
                        self.in_party[i] = True
                        self._party_change(j, +1)
                        self._penalise(j)
                break
        hold = self.holds[i, self.n_holds[i] % len(self.holds[i])]
        self.n_holds[i] += 1
        return self._delay(hold)

    def _land(self, i: int, cut: bool) -> None:
        """The macro-action ended: a finished flight ends at its goal, a cut one on its segment."""
        if self.flight[i] is None:
            return
        origin, goal, t0, length = self.flight[i]
        if cut and length > 0:
            frac = min(1.0, self.cfg.v_uav * (self.env.now - t0) / length)
            self.pos[i] = (origin[0] + frac * (goal[0] - origin[0]),
                           origin[1] + frac * (goal[1] - origin[1]))
        else:
            self.pos[i] = goal
        self.flight[i] = None

    # --- fires -----------------------------------------------------------------------------------

    def _health_now(self, j: int) -> float:
        if not self.alive[j]:
            return 0.0
        return max(0.0, self.health[j] - self.party[j] * (self.env.now - self.t_update[j]))

    def _party_change(self, j: int, delta: int) -> None:
        """Drain fire j's health at the old rate, change its party size, and make it re-plan."""
        if not self.alive[j]:
            return
        now = self.env.now
        self.health[j] = self.health[j] - self.party[j] * (now - self.t_update[j])
        self.t_update[j] = now
        self.party[j] += delta
        self.fire_procs[j].interrupt()

    def _penalise(self, j: int) -> None:
        """A UAV just joined fire j's extinguish party: penalise if it already had a member."""
        if self.party[j] < 2:
            return
        for i in range(self.cfg.n_agents):
            member = self.in_party[i] and self.attacking[i] == j
            if member or not self.cfg.quirk_q2_penalty_party_only:
                self._accrue(i, self.cfg.r_pen)

    def _extinguish(self, j: int) -> None:
        self.alive[j] = False
        for i in range(self.cfg.n_agents):
            self._accrue(i, self.cfg.r_ext)
        for i in range(self.cfg.n_agents):
            if self.interest[i] == j:
                self.uav_procs[i].interrupt()
        if not any(self.alive):
            self._end()

    # --- bookkeeping -----------------------------------------------------------------------------

    def _decisions(self, i: int) -> int:
        """How many decisions UAV i has made so far."""
        return 0 if self.current[i] < 0 else self.rec[self.current[i]]["index"] + 1

    def _delay(self, d: float) -> float:
        return fs_delay(self.env.now, d, self.dt)

    def _accrue(self, i: int, r: float) -> None:
        rec = self.rec[self.current[i]]
        rec["reward"] += math.exp(-self.cfg.gamma * (self.env.now - rec["time"])) * r
        self.returns[i] += r

    def _end(self) -> None:
        self.done = True
        self.t_end = self.env.now
        for i in range(self.cfg.n_agents):
            rec = self.rec[self.current[i]]
            rec["duration"] = self.t_end - rec["time"]


class ReferenceEnv:
    """The SimPy model behind the BatchEnv interface: episodes one after another, the policy asked
    once per decision (a one-row DecisionBatch)."""

    name = "wildfire"

    def __init__(self, cfg: WildfireConfig):
        cfg.validate()
        self.cfg = cfg
        self.obs_dim = cfg.obs_dim
        self.n_actions = cfg.n_actions
        self.n_agents = cfg.n_agents
        self.gamma = cfg.gamma

    def rollout(self, policy: Policy, n_episodes: int,
                seed: int | np.random.SeedSequence) -> Rollout:
        return self.simulate(policy, draw_episodes(self.cfg, n_episodes, seed))

    def simulate(self, policy: Policy, draws: EpisodeDraws) -> Rollout:
        """Run the episodes of ``draws`` (tests script start positions and hold durations)."""
        recs, returns, ends, events = [], [], [], []
        for e in range(draws.n_episodes):
            model = WildfireModel(self.cfg, draws.starts[e], draws.holds[e])
            while True:
                model.advance()
                if not model.pending:
                    break
                i = model.pending[0]
                rec = model.rec[model.current[i]]
                batch = DecisionBatch(obs=np.array([rec["obs"]]), episode=np.array([e]),
                                      agent=np.array([i]), index=np.array([rec["index"]]))
                model.act(i, check_actions(policy(batch), 1, self.n_actions)[0])
            recs += [dict(r, episode=e) for r in model.rec]
            returns.append(model.returns)
            ends.append(model.t_end)
            events.append(model.events)
        col = lambda key, dtype=float: np.array([r[key] for r in recs], dtype=dtype)  # noqa: E731
        return rollout_from_records(
            episode=col("episode", np.int64), agent=col("agent", np.int64),
            index=col("index", np.int64), time=col("time"),
            obs=np.array([r["obs"] for r in recs]).reshape(len(recs), self.obs_dim),
            actions=col("action", np.int64), rewards=col("reward"), durations=col("duration"),
            agent_returns=np.array(returns).reshape(draws.n_episodes, self.n_agents),
            end_time=np.array(ends), events=np.array(events, dtype=np.int64))


def check_actions(actions: np.ndarray, n: int, n_actions: int) -> np.ndarray:
    """The policy's answer as (n,) int64 actions, or ValueError."""
    a = np.asarray(actions)
    if a.shape != (n,) or not np.issubdtype(a.dtype, np.integer) or (a.size and (
            a.min() < 0 or a.max() >= n_actions)):
        raise actions_error(a, n, n_actions)
    return a.astype(np.int64)


def actions_error(a: np.ndarray, n: int, n_actions: int) -> ValueError:
    """The error for a policy answer ``a`` that is not (n,) integer actions in [0, n_actions)."""
    return ValueError(f"policy must return {n} integer actions in [0, {n_actions}), got "
                      f"shape {a.shape} dtype {a.dtype}")
