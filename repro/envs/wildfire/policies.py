"""Heuristic wildfire policies: callables on a DecisionBatch, vectorised over its rows.

They read the observation layout of docs/semantics.md section 3.6: own x, y; per observed fire
(closest first) distance, level, interest party size, status, remaining health; sojourn time. Action
k < n_observed flies to the k-th closest fire, action n_observed holds.

"Other UAV interested" is read from the interest party size. The observation does not say whether
the observer itself is in the party, so the policies assume what the dynamics make true: a UAV at
a fire got there by flying to it or holding at it, and is in its interest party until it acts
again. At the fire it is at, "no other UAV interested" is therefore a party size of at most 1.

Each policy owns its randomness: by default a numpy Generator; tests pass ``uniforms``, a function
giving each row its random numbers from (episode, agent, index), so that two engines that batch
decisions differently still see the same numbers per decision.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from repro.core.rollout import DecisionBatch
from repro.envs.wildfire.params import DIST, INTEREST, STATUS, fire_blocks

N_UNIFORMS = 2
"""Random numbers a policy may use per decision."""
FLOWCHART_HOLD_ALONE = 0.84
"""Paper, Fig. "appxpolicy": probability of holding at a live fire nobody else is interested in."""
FLOWCHART_HOLD_SHARED = 0.27
"""Probability of holding at a live fire another UAV is interested in."""
FLOWCHART_TARGET = (0.15, 0.15, 0.68, 0.01, 0.01)
"""Probabilities of flying to the closest, 2nd, ..., 5th closest fire when not holding."""
OBSERVED_AT_FIRE_TOL = 1e-2
"""An observed distance (m) to a fire below this reads as "at" that fire, for the heuristics and
for classifying learned behaviour (C6, C7). It is not the simulator's rule,
``WildfireConfig.at_fire_tol`` (1e-3 m, the released code's constant: a hold joins a fire that
close; under Q6 a shorter flight leaves the UAV where it was). This one only has to recognise a
UAV that arrived at a fire, up to round-off and the 1e-3 m that Q6 may leave, and stay below half
the 0.02 m between cluster-mates, so that it never names two fires. So a UAV 1e-3 to 1e-2 m off a
fire (a flight cut just short of it) reads as at the fire, though a hold there joins nothing.
Making the two one would change the committed C6 and C7 numbers."""

Uniforms = Callable[[DecisionBatch], np.ndarray]


class HeuristicPolicy:
    """Base: owns the random source; subclasses map (observations, uniforms) to actions."""

    def __init__(self, rng: np.random.Generator | None = None, *, n_observed: int = 5,
                 uniforms: Uniforms | None = None):
        if (rng is None) == (uniforms is None):
            raise ValueError("give exactly one of rng and uniforms")
        self.rng = rng
        self.uniforms = uniforms
        self.n_observed = n_observed

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        u = self.rng.random((len(batch), N_UNIFORMS)) if self.uniforms is None else \
            np.asarray(self.uniforms(batch))
        return self.act(np.asarray(batch.obs), u)

    def fires(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """(M, n_observed) per-fire columns of the observations, closest first."""
        block = fire_blocks(obs, self.n_observed)
        return dict(dist=block[..., DIST], interest=block[..., INTEREST],
                    alive=block[..., STATUS] > 0.5)

    def random_action(self, u: np.ndarray) -> np.ndarray:
        return np.minimum((u * (self.n_observed + 1)).astype(np.int64), self.n_observed)

    def act(self, obs: np.ndarray, u: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class RandomPolicy(HeuristicPolicy):
    """Uniform over the actions."""

    def act(self, obs: np.ndarray, u: np.ndarray) -> np.ndarray:
        return self.random_action(u[:, 0])


class NearestPolicy(HeuristicPolicy):
    """Walk the observed live fires from the closest: hold at it if at it and nobody else is
    interested; else fly to it if nobody is interested; else try the next. If none qualifies, a
    uniformly random action."""

    def act(self, obs: np.ndarray, u: np.ndarray) -> np.ndarray:
        f = self.fires(obs)
        at = f["dist"] < OBSERVED_AT_FIRE_TOL
        hold = f["alive"] & at & (f["interest"] <= 1)
        fly = f["alive"] & (f["interest"] == 0)
        ok = hold | fly
        first = np.argmax(ok, axis=1)
        rows = np.arange(len(obs))
        action = np.where(hold[rows, first], self.n_observed, first)
        return np.where(ok.any(axis=1), action, self.random_action(u[:, 0]))


class FlowchartPolicy(HeuristicPolicy):
    """The paper's approximation of the learned policy (Fig. "appxpolicy"): at a live fire hold
    with probability 0.84 if no other UAV is interested, 0.27 if one is; otherwise fly to the
    k-th closest fire with the probabilities FLOWCHART_TARGET."""

    def act(self, obs: np.ndarray, u: np.ndarray) -> np.ndarray:
        f = self.fires(obs)
        at_live = f["alive"][:, 0] & (f["dist"][:, 0] < OBSERVED_AT_FIRE_TOL)
        others = f["interest"][:, 0] - 1  # the UAV itself is in the party of the fire it is at
        p_hold = np.where(others <= 0, FLOWCHART_HOLD_ALONE, FLOWCHART_HOLD_SHARED)
        hold = at_live & (u[:, 0] < p_hold)
        cdf = np.cumsum(FLOWCHART_TARGET[:self.n_observed])
        target = np.minimum(np.searchsorted(cdf / cdf[-1], u[:, 1], side="right"),
                            self.n_observed - 1)
        return np.where(hold, self.n_observed, target).astype(np.int64)


POLICIES: dict[str, type[HeuristicPolicy]] = {
    "random": RandomPolicy, "nearest": NearestPolicy, "flowchart": FlowchartPolicy,
}
"""Name (as on the command line) -> policy class."""
