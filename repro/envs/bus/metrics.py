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
                       band_min: float = REGULARITY_BAND_MIN) -> float:
    """Minutes from the episode start until every later headway stays within H +- band.

    It is the time of the last arrival whose |h - H| > band (0 if there is none), and NaN when the
    episode's last arrival is itself irregular (regularity never reached). One episode's table.
    """
    bad = (arrivals.h_min - headway_min).abs() > band_min
    if not bad.any():
        return 0.0
    if bool(bad.iloc[-1]):
        return float("nan")
    return float(arrivals.time_min[bad].max())


def load_variance_per_stop(loads: pd.DataFrame) -> pd.Series:
    """Variance over buses of the load at arrival, per stop (from :func:`cycle_loads`)."""
    return loads.groupby("stop").load.var(ddof=0)
