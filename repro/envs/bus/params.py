"""Parameters of the bus corridor (docs/semantics.md section 4.1, paper Table "bbparams"), and the
switches B1-B5 between the authors' released simulator (the default) and the paper's prose
(docs/semantics.md section 4.9)."""

from __future__ import annotations

import numbers
from dataclasses import dataclass
from typing import ClassVar

from repro.core.config import Validated

DECISION_LATENCY = 1e-5
"""Seconds between a bus's observation and the start of its action under B5 (the released
simulator's ACTION_WAIT_TIME, as in the wildfire)."""
OBS_DIM = 4
"""Observation: [stop index (0-based), headway h (s, or -1 under B2; min without B2), load at
arrival (pax), time since the bus's previous action started (s)]; both models write it."""
SWITCHES = ("b1_reward", "b2_headway", "b3_boarding", "b4_round_half_even", "b5_timing")
"""The BusConfig fields of B1-B5: True follows the released simulator, False the paper's prose."""


@dataclass(frozen=True)
class BusConfig(Validated):
    """The bus corridor. Times are in seconds unless a field says minutes."""

    n_buses: int = 6
    """N: buses, one agent each; at t = 0 they queue for Stop 1 in index order."""
    n_stops: int = 10
    """K: stops on the loop (Stop K is followed by Stop 1)."""
    l_max: int = 75
    """L_max: bus capacity in passengers."""
    travel_time: float = 180.0
    """rt: travel time between consecutive stops (s), the same for every link."""
    t_alight: float = 1.8
    """t_a: seconds per alighting passenger."""
    t_board: float = 3.0
    """t_b: seconds per boarding passenger."""
    headway: float = 6.0
    """H: planned headway (minutes); the reward penalises (h - H)^2."""
    t_hold: float = 30.0
    """T_hold: holding time per unit of action (s); action a holds a * T_hold."""
    n_actions: int = 4
    """Actions a in {0, ..., n_actions - 1}."""
    alight_fraction: tuple[float, ...] = (1.0, 0.0, 0.1, 0.25, 0.25, 0.5, 0.5, 0.1, 0.75, 0.1)
    """q_k: fraction of the load that alights at each stop."""
    arrival_rate: tuple[float, ...] = (1.5, 2.25, 1.4, 4.5, 2.55, 1.8, 1.43, 1.05, 0.75, 0.45)
    """nu_k: passenger arrival rate at each stop (pax/min); also the stop's reward weight."""
    horizon: float = 3 * 3600.0
    """Episode length (s): arrivals at t < horizon count; running macro-actions are then cut."""
    gamma: float = 1e-5
    """Continuous-time discount rate (1/s) inside macro-actions and for M-GAE (paper Table 2)."""
    b1_reward: bool = True
    """B1, released reward: an arrival gives every agent -nu_k (h - H)^2 in pax/s and seconds (60
    times the minutes reading), and nothing when h <= 0 or at a bus's first two stop visits (its
    start at Stop 1 and its first arrival by travel). Off: -nu_k (h - H)^2 in pax/min and minutes
    at every visit, the start at Stop 1 included."""
    b2_headway: bool = True
    """B2, released headway: h = arrival time minus the latest departure of the bus ahead (Bus N
    for Bus 1) from the stop, -1 if it has not left the stop yet and at a bus's start at Stop 1;
    observed in seconds. Off: h = arrival time minus the latest departure of any bus (episode
    start if none yet), observed in minutes."""
    b3_boarding: bool = True
    """B3, released boarding: B = round(nu_k hb) capped by the free seats, hb the current time at a
    bus's first two stop visits and h from the third on (nu_k in pax/s, so h = -1 boards nobody).
    Off: hb = h at every visit (nu_k in pax/min, h in minutes)."""
    b4_round_half_even: bool = True
    """B4: U and B rounded half to even (Python's round). Off: half up, floor(x + 0.5)."""
    b5_timing: bool = True
    """B5, released decision timing: a bus observes two same-instant SimPy steps after it gets the
    stop (its service process ends, then the wait for it), its action starts DECISION_LATENCY later
    (it keeps the stop meanwhile; the macro-action and its discounting start then), and dwell and
    hold are two timeouts. Off: it observes on getting the stop and acts at once, dwell + hold in
    one timeout."""

    ALIASES: ClassVar[dict[str, str]] = {"b1": "b1_reward", "b2": "b2_headway",
                                         "b3": "b3_boarding", "b4": "b4_round_half_even",
                                         "b5": "b5_timing"}
    """Older flags of the switches (``--b1``, ``--no-b1``), still taken."""

    def validate(self) -> None:
        for name, low in (("n_buses", 1), ("n_stops", 2), ("l_max", 1), ("n_actions", 1)):
            value = getattr(self, name)
            self.check(isinstance(value, numbers.Integral) and value >= low, name,
                       f"an integer >= {low}")
        self.check(len(self.alight_fraction) == self.n_stops, "alight_fraction",
                   f"{self.n_stops} values (one per stop)")
        self.check(len(self.arrival_rate) == self.n_stops, "arrival_rate",
                   f"{self.n_stops} values (one per stop)")
        self.check(all(0.0 <= q <= 1.0 for q in self.alight_fraction), "alight_fraction",
                   "values in [0, 1]")
        self.check(all(v >= 0.0 for v in self.arrival_rate), "arrival_rate", "values >= 0")
        self.check(self.travel_time > 0.0, "travel_time", "> 0")
        # negative service times would schedule events in the past (SimPy refuses them)
        self.check(self.t_alight >= 0.0, "t_alight", ">= 0")
        self.check(self.t_board >= 0.0, "t_board", ">= 0")
        self.check(self.headway > 0.0, "headway", "> 0")
        self.check(self.t_hold >= 0.0, "t_hold", ">= 0")
        self.check(self.horizon > 0.0, "horizon", "> 0")
        # 0 (no discounting) is a valid corridor; training needs gamma > 0 (the trainer checks)
        # above 1/s a macro-action's later rewards vanish below double precision (e^-745)
        self.check(0.0 <= self.gamma <= 1.0, "gamma", "a number from 0 to 1 per second (> 0 to "
                   "train)")
        for name in SWITCHES:
            self.check(isinstance(getattr(self, name), bool), name, "True or False")

    BEFORE_ADDED: ClassVar[dict[str, bool]] = dict.fromkeys(SWITCHES, False)
    """Runs recorded before B1-B5 existed ran the corrected semantics."""

    @classmethod
    def corrected(cls, **fields) -> BusConfig:
        """The paper's prose: B1-B5 all off (``--corrected``), other fields as given."""
        return cls(**{**dict.fromkeys(SWITCHES, False), **fields})

    @property
    def semantics(self) -> str:
        """'released' (B1-B5 on), 'corrected' (all off), else the switches on, e.g. 'b1-b4'."""
        on = [name for name in SWITCHES if getattr(self, name)]
        if len(on) == len(SWITCHES):
            return "released"
        return "-".join(name.split("_")[0] for name in on) or "corrected"

    @property
    def max_arrivals_per_bus(self) -> int:
        """An upper bound on one bus's arrivals in an episode (each stop visit takes >= rt)."""
        return int(self.horizon // self.travel_time) + 2
