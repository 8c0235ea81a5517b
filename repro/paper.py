"""Every number this suite quotes from the paper (Menda et al., "Deep Reinforcement Learning for
Event-Driven Multi-Agent Decision Processes"), once: the studies draw them beside their own, the
claims judge against them and print them. Imports nothing of the suite, so any layer may use it.

The bus loads are the data the paper embeds in its bus load figure (fig:bbload): the pgfplots
coordinates of the three panels in the paper's LaTeX, which the authors' BusBunching/plotdata.jl
wrote: for buses 1-5 (of 6), each bus's stop-visit records 40..50 (1-based, the start at Stop 1
being the first) of a 6 h episode, plotted against the 0-based stop index (9, 0, 1, ..., 9: Stop 10
of the 4th cycle, then Stops 1-10 of the 5th). The arrival-time figure (fig:bbarrival_times) is
included from files the LaTeX does not embed, so it has no data here.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pandas is imported where the loads are compared: importing this stays light
    import pandas as pd

# --- races (Table 5) ------------------------------------------------------------------------------

RACE_BETA = {"Exponential": (2.216, 0.055), "Chi-Squared": (2.213, 0.045), "Gamma": (2.219, 0.037)}
"""Table 5: the exponent beta of the largest safe dT ~ alpha N^-beta (delta = 0.1), with its
standard error, per event-time distribution (Exp(1), Chi2(5), Gamma(5, 1))."""
RACE_DISTRIBUTIONS = {"Exponential": "Exp(1)", "Chi-Squared": "Chi2(5)", "Gamma": "Gamma(5,1)"}
"""How the paper names each distribution of :data:`RACE_BETA`."""

# --- wildfire (Sec. 5.2, Figs. 6 and 7) -----------------------------------------------------------

BEHAVIOUR_FREQUENCIES = dict(hold_shared=0.27, hold_alone=0.84, fly_rank_1=0.15, fly_rank_2=0.15,
                             fly_rank_3=0.68, closest_cluster=0.98)
"""Sec. 5.2 (C6): how often a long ED-trained policy holds where another UAV is interested
(shared) or not (alone), flies to the nearest, 2nd and 3rd nearest fire, and stays in the closest
cluster; fly_rank_4/5 are not given."""
FLOWCHART_WORSE = 0.28
"""Sec. 5.2 (C7): the flowchart of C6 does this much worse (ADR) than the learned policy."""
TRANSFER_ADR = {
    "ED": (2.780, 0.014), "FS-0.1": (2.771, 0.018), "FS-0.316": (2.745, 0.015),
    "FS-1": (2.789, 0.009), "FS-3.16": (2.212, 0.082), "FS-10": (1.841, 0.179),
    "FS-1 (T_health=2.9999)": (1.937, 0.041),
}
"""Fig. 7 ("transferperformance"): ADR on ED, mean and standard error over 5 policies, per
training simulator."""
C9_PAIR = ("FS-1 (T_health=2.9999)", "FS-1")
"""C9's pair of training simulators: the degraded one, then the one it is compared with."""

# --- the bus (Sec. 5.1, Figs. 3-5) ----------------------------------------------------------------

BUS_LAMBDA = 2.0
"""The paper's bus lambda: C1 compares the MLP trained with it."""
BUS_REGULARITY_MIN = {"mlp": 100.0, "thresholds": 200.0}
"""Uniform arrivals after about 100 min (MLP) and 200 min (Optimized Thresholds)."""
BUS_BUSES_DRAWN = 5
"""The buses the paper's bus figures draw (buses 1-5 of 6)."""

PAPER_RECORDS = tuple(range(40, 51))
"""The records plotdata.jl picks (``df_sub[4*10:5*10, :]``, 1-based and inclusive)."""
PAPER_STOPS = (10, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10)
"""The 1-based stop of each of those records."""
PAPER_LOADS = {
    "nohold": [[50, 64, 60, 75, 75, 75, 75, 75, 75, 75, 50]] + [[0] * 11] * 4,
    "thresholds": [[29, 33, 21, 51, 64, 75, 75, 56, 43, 49, 18],
                   [12, 14, 10, 23, 30, 48, 53, 39, 29, 34, 13],
                   [11, 13, 9, 23, 30, 47, 51, 37, 28, 32, 13],
                   [10, 12, 9, 21, 28, 43, 46, 34, 26, 30, 12],
                   [1, 2, 4, 11, 15, 27, 30, 24, 20, 24, 10]],
    "mlp": [[13, 16, 11, 28, 36, 59, 61, 40, 26, 28, 10],
            [11, 13, 9, 22, 28, 43, 45, 32, 21, 23, 8],
            [12, 14, 10, 24, 31, 49, 54, 39, 27, 29, 9],
            [11, 13, 10, 25, 32, 51, 54, 39, 28, 32, 12],
            [10, 12, 11, 26, 33, 53, 58, 42, 31, 36, 14]],
}
"""Load at arrival per paper panel (No Holding, Optimized Thresholds, the trained policy), per
bus 1-5, per record 40..50."""
PAPER_PANEL = {"nohold": "nohold", "authors": "thresholds", "thresholds": "thresholds",
               "mlp": "mlp", "gru": "mlp", "gru-greedy": "mlp"}
"""Our policy -> the paper panel it is compared with (both thresholds policies with the paper's
thresholds panel, which the authors' thresholds drew; the paper's "MLP" panel was drawn by the
released GRU policy, sampled: ``busbunchingenv.py`` ``test()``)."""


def paper_loads(policy: str) -> pd.DataFrame:
    """The paper panel that ``policy`` is compared with: columns bus (1-based), record, stop
    (1-based), load."""
    import pandas as pd

    rows = [dict(bus=b + 1, record=r, stop=k, load=load)
            for b, series in enumerate(PAPER_LOADS[PAPER_PANEL[policy]])
            for r, k, load in zip(PAPER_RECORDS, PAPER_STOPS, series)]
    return pd.DataFrame(rows)
