"""What the bus figures and claims measure: arrival tables, 4th-cycle loads, time to regularity.

A bus's c-th cycle is its c-th visit to Stops 1..K (its arrivals (c-1) K + 1 .. c K, counting from
its first arrival at Stop 1 at the start of the episode).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from repro.core.rollout import Rollout

REGULARITY_BAND_MIN = 1.0
"""Half-width (minutes) of the headway band around H that counts as regular."""
REGULARITY_SHARE = 0.9
"""Share of the later headways that must lie in the band for the arrivals to count as regular."""
REGULARITY_MIN_TAIL = 60
"""Arrivals that must follow the time of regularity: one cycle of the fleet (6 buses x 10 stops)."""


def arrival_table(rollout: Rollout, n_stops: int) -> pd.DataFrame:
    """One row per arrival: episode, time_s, time_min, bus, stop (1-based), cycle (1-based), h_min,
    load (at arrival), alight, board; ordered by episode then processing order."""
    a = rollout.info["arrivals"]
    df = pd.DataFrame({"episode": a["episode"], "time_s": a["time"], "time_min": a["time"] / 60.0,
                       "bus": a["bus"] + 1, "stop": a["stop"] + 1, "h_min": a["h"],
                       "load": a["load"], "alight": a["alight"], "board": a["board"]})
    df["cycle"] = df.groupby(["episode", "bus"]).cumcount() // n_stops + 1
    return df


def cycle_loads(arrivals: pd.DataFrame, cycle: int = 4) -> pd.DataFrame:
    """Load at arrival of every bus at every stop in its ``cycle``-th cycle (one episode's table):
    rows bus, stop, load, and rank = the bus's place in the order of arrival at Stop 1 in that
    cycle (0 = the leader)."""
    c = arrivals[arrivals.cycle == cycle]
    first = c[c.stop == 1].sort_values("time_s")
    rank = {b: r for r, b in enumerate(first.bus)}
    out = c[["bus", "stop", "load"]].sort_values(["bus", "stop"]).reset_index(drop=True)
    out["rank"] = out.bus.map(rank).astype("int64")
    return out


def time_to_regularity(arrivals: pd.DataFrame, headway_min: float,
                       band_min: float = REGULARITY_BAND_MIN, share: float = REGULARITY_SHARE,
                       min_tail: int = REGULARITY_MIN_TAIL) -> float:
    """Minutes from the episode start until the arrivals are regular (one episode's table, in
    time order): the time of the earliest arrival from which on at least ``share`` of the
    headways lie within H +- band and at least ``min_tail`` arrivals remain; NaN if there is none.

    A share rather than "every later headway" so that one stray arrival (typically the last one
    before the horizon) cannot decide the answer; the minimum tail so that a short lucky stretch
    just before the horizon does not count as regularity reached.
    """
    ok = np.abs(arrivals.h_min.to_numpy() - headway_min) <= band_min
    tail_n = np.arange(len(ok), 0, -1)
    tail_ok = np.cumsum(ok[::-1])[::-1]
    regular = (tail_ok >= share * tail_n) & (tail_n >= min_tail)
    if not regular.any():
        return float("nan")
    return float(arrivals.time_min.to_numpy()[np.argmax(regular)])


def load_variance_per_stop(loads: pd.DataFrame) -> pd.Series:
    """Variance over buses of the load at arrival, per stop (from :func:`cycle_loads`)."""
    return loads.groupby("stop").load.var(ddof=0)
