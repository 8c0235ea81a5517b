"""What the bus figures and claims measure: arrival tables, the paper's load records, time to
regularity.

A bus's r-th record is its r-th stop visit, its start at Stop 1 being the first (as the released
simulator records them); its c-th cycle is records (c-1) K + 1 .. c K.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from repro.core.rollout import Rollout
from repro.paper import PAPER_RECORDS

REGULARITY_BAND_MIN = 1.0
"""Half-width (minutes) of the headway band around H that counts as regular."""
REGULARITY_SHARE = 0.9
"""Share of the later headways that must lie in the band for the arrivals to count as regular."""
REGULARITY_MIN_TAIL = 60
"""Arrivals that must follow the time of regularity: one cycle of the fleet (6 buses x 10 stops)."""


def arrival_table(rollout: Rollout, n_stops: int) -> pd.DataFrame:
    """One row per served stop visit: episode, time_s, time_min, bus, stop (1-based), record and
    cycle (1-based), h_min (NaN: unknown under B2), load (at arrival), alight, board; ordered by
    episode then processing order."""
    a = rollout.info["arrivals"]
    df = pd.DataFrame({"episode": a["episode"], "time_s": a["time"], "time_min": a["time"] / 60.0,
                       "bus": a["bus"] + 1, "stop": a["stop"] + 1, "h_min": a["h"],
                       "load": a["load"], "alight": a["alight"], "board": a["board"]})
    df["record"] = df.groupby(["episode", "bus"]).cumcount() + 1
    df["cycle"] = (df.record - 1) // n_stops + 1
    return df


def record_loads(arrivals: pd.DataFrame, records=PAPER_RECORDS) -> pd.DataFrame:
    """Load at arrival of every bus at its ``records`` (default: those the paper's load figure
    shows), from one episode's table: columns bus, record, stop, load."""
    sel = arrivals[arrivals.record.isin(records)]
    return sel[["bus", "record", "stop", "load"]].sort_values(["bus", "record"]).reset_index(
        drop=True)


def l1_per_point(table: pd.DataFrame) -> float:
    """Mean |ours - paper| over the paper's points, from one policy's rows of bus_load.csv
    (columns source, bus, record, load); NaN if one of our points is missing."""
    paper, ours = table[table.source == "paper"], table[table.source == "ours"]
    both = paper.merge(ours, on=["bus", "record"], how="left", suffixes=("_p", "_o"))
    return float((both.load_p - both.load_o).abs().mean(skipna=False))


UNIFORM_WINDOW_MIN = 30.0
"""Width (minutes) of the windows in which :func:`time_to_uniform` counts headways."""


def time_to_uniform(arrivals: pd.DataFrame, headway_min: float,
                    band_min: float = REGULARITY_BAND_MIN, share: float = REGULARITY_SHARE,
                    window_min: float = UNIFORM_WINDOW_MIN) -> float:
    """Minutes from the episode start until the arrivals first look uniform (one episode's
    table): the start of the first window (0, 30, 60, ... min) in which at least ``share`` of the
    known headways lie within H +- band; NaN if there is none. The paper says when each policy
    "achieves" uniformity, judged from its arrival figure: a first time, which later stray
    windows do not undo (:func:`time_to_regularity` asks for it to last)."""
    ok = window_shares(arrivals, headway_min, band_min, window_min)
    hit = ok.index[ok.to_numpy() >= share]
    return float(hit[0] * window_min) if len(hit) else float("nan")


def window_shares(arrivals: pd.DataFrame, headway_min: float,
                  band_min: float = REGULARITY_BAND_MIN,
                  window_min: float = UNIFORM_WINDOW_MIN) -> pd.Series:
    """Per window (0, 30, 60, ... min; indexed by its number) of one episode's table, the share
    of its known headways that lie within H +- band: how near to uniform each window comes."""
    known = arrivals[arrivals.h_min.notna()]
    return (np.abs(known.h_min - headway_min) <= band_min).groupby(
        (known.time_min // window_min).astype(int)).mean()


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


def load_variance_per_record(loads: pd.DataFrame) -> pd.Series:
    """Variance over buses of the load at arrival, per record (from :func:`record_loads`)."""
    return loads.groupby("record").load.var(ddof=0)
