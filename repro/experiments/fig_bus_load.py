"""Load at arrival of the buses at the records the paper's load figure shows (Fig. bbload; C4,
C5): a 6 h episode, each bus's stop-visit records 40..50 (Stop 10 of its 4th cycle, Stops 1-10 of
its 5th; plotdata.jl), one panel per policy, the paper's five series as black markers beside
ours (buses 1-5; ``--all-buses`` adds Bus 6, which the paper did not draw).

Writes results/bus_load.csv (source: paper or ours, policy, bus, record, stop, load; the paper's
rows of a policy are the panel it is compared with: the thresholds panel for both thresholds
policies) and figures/bus_load.
"""

from __future__ import annotations

import argparse

import pandas as pd

from repro.core.io import save_figure
from repro.envs.bus import BusConfig
from repro.envs.bus.metrics import record_loads
from repro.envs.bus.paper_data import PAPER_RECORDS, PAPER_STOPS, paper_loads
from repro.experiments.fig_bus_arrivals import (PAPER_BUSES, TITLES, add_policy_arguments,
                                                run_policy_figure)

LOAD_CSV = "bus_load.csv"
COLUMNS = ["source", "policy", "bus", "record", "stop", "load"]


def loads(arrivals: pd.DataFrame) -> pd.DataFrame:
    frames = []
    for name, grp in arrivals.groupby("policy", sort=False):
        frames.append(paper_loads(name).assign(source="paper", policy=name))
        frames.append(record_loads(grp).assign(source="ours", policy=name))
    return pd.concat(frames, ignore_index=True)[COLUMNS]


def plot(table: pd.DataFrame, stem, all_buses: bool = False) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(dict.fromkeys(table.policy))
    fig, axes = plt.subplots(1, len(names), figsize=(4.5 * len(names), 3.6), sharey=True,
                             squeeze=False)
    for ax, name in zip(axes[0], names):
        sel = table[table.policy == name]
        for bus, grp in sel[sel.source == "ours"].groupby("bus"):
            if all_buses or bus <= PAPER_BUSES:
                ax.plot(grp.record, grp.load, ".-", ms=4, lw=0.8, label=f"Bus {bus}")
        paper = sel[sel.source == "paper"]
        ax.plot(paper.record, paper.load, "o", mfc="none", mec="k", ms=7, lw=0,
                label="paper (buses 1-5)")
        ax.axhline(BusConfig().l_max, color="k", lw=0.8, ls="--")
        ax.set_title(TITLES.get(name, name))
        ax.set_xlabel("Stop (records 40-50: Stop 10 of cycle 4, cycle 5)")
        ax.set_xticks(PAPER_RECORDS, [str(k) for k in PAPER_STOPS])
        ax.grid(True, alpha=0.3)
    axes[0][0].set_ylabel("Load at arrival [pax]")
    axes[0][-1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))
    save_figure(fig, stem)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_policy_arguments(p)


def run(args: argparse.Namespace) -> int:
    return run_policy_figure(args, command="fig-bus-load", csv_name=LOAD_CSV, table_of=loads,
                             plot_table=plot)
