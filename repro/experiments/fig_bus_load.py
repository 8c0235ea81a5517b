"""Load at arrival of every bus at every stop in its 4th cycle, one panel per policy (paper Fig.
bbload; claim C4). Writes results/bus_load.csv (policy, bus, stop, load, rank: 0 = the bus first at
Stop 1 in that cycle) and figures/bus_load."""

from __future__ import annotations

import argparse

import pandas as pd

from repro.core.io import save_figure
from repro.envs.bus import BusConfig
from repro.envs.bus.metrics import cycle_loads
from repro.experiments.bus_eval import CYCLE
from repro.experiments.fig_bus_arrivals import TITLES, add_policy_arguments, run_policy_figure

LOAD_CSV = "bus_load.csv"


def loads(arrivals: pd.DataFrame) -> pd.DataFrame:
    frames = [cycle_loads(grp, CYCLE).assign(policy=name)
              for name, grp in arrivals.groupby("policy", sort=False)]
    out = pd.concat(frames, ignore_index=True)
    return out[["policy", "bus", "stop", "load", "rank"]].assign(cycle=CYCLE)


def plot(table: pd.DataFrame, stem) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(dict.fromkeys(table.policy))
    fig, axes = plt.subplots(1, len(names), figsize=(4.5 * len(names), 3.6), sharey=True,
                             squeeze=False)
    l_max = BusConfig().l_max
    for ax, name in zip(axes[0], names):
        for bus, grp in table[table.policy == name].groupby("bus"):
            ax.plot(grp.stop, grp.load, "o-", ms=3, lw=0.8, label=f"Bus {bus}")
        ax.axhline(l_max, color="k", lw=0.8, ls="--")
        ax.set_title(f"{TITLES.get(name, name)} (cycle {CYCLE})")
        ax.set_xlabel("Stop")
        ax.set_xticks(range(1, BusConfig().n_stops + 1))
        ax.grid(True, alpha=0.3)
    axes[0][0].set_ylabel("Load at arrival [pax]")
    axes[0][-1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))
    save_figure(fig, stem)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_policy_arguments(p)


def run(args: argparse.Namespace) -> int:
    return run_policy_figure(args, command="fig-bus-load", csv_name=LOAD_CSV, table_of=loads,
                             plot_table=plot)
