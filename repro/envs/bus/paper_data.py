"""The data the paper embeds in its bus load figure (fig:bbload), as input data for comparisons.

Source: the pgfplots coordinates of the three panels in the paper's LaTeX (Menda et al., "Deep
Reinforcement Learning for Event-Driven Multi-Agent Decision Processes", fig:bbload), which the
authors' BusBunching/plotdata.jl wrote: for buses 1-5 (of 6), each bus's stop-visit records 40..50
(1-based, the start at Stop 1 being the first) of a 6 h episode, plotted against the 0-based stop
index (9, 0, 1, ..., 9: Stop 10 of the 4th cycle, then Stops 1-10 of the 5th). The arrival-time
figure (fig:bbarrival_times) is included from files the LaTeX does not embed, so it has no data
here.
"""

from __future__ import annotations

import pandas as pd

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
               "mlp": "mlp"}
"""Our policy -> the paper panel it is compared with (both thresholds policies with the paper's
thresholds panel, which the authors' thresholds drew)."""


def paper_loads(policy: str) -> pd.DataFrame:
    """The paper panel that ``policy`` is compared with: columns bus (1-based), record, stop
    (1-based), load."""
    rows = [dict(bus=b + 1, record=r, stop=k, load=load)
            for b, series in enumerate(PAPER_LOADS[PAPER_PANEL[policy]])
            for r, k, load in zip(PAPER_RECORDS, PAPER_STOPS, series)]
    return pd.DataFrame(rows)
