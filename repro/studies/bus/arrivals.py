"""Arrival times of the buses at the ten stops, one panel per policy (paper Fig.
bbarrival_times): a 6 h episode, buses 1-5 as the paper drew them (``--all-buses``: all six).

Writes results/bus_arrivals.csv (every served stop visit of one 6 h episode per policy, all
buses) and figures/bus_arrivals. Panels: No Holding, the authors' thresholds, ours, the trained
MLP, which is the lambda sweep's best run (highest final return; ``--mlp-run`` names another),
acting greedily; with ``--policies ... gru gru-greedy`` also the released GRU policy that drew the
paper's pictures, sampled and greedy, the best of its runs, trained here where they are not
finished (:mod:`repro.studies.bus.gru_runs`; ``--gru-run`` names another). A new policy is one
more name in ``POLICIES`` / ``make_policy``. The figure is
one column wide, the panels two by two; ``--replot`` draws it again from the CSV.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from repro.paper import BUS_BUSES_DRAWN
from repro.runs.results import save_figure
from repro.studies.bus import pictures
from repro.studies.bus.pictures import (PictureConfig, add_policy_arguments, policy_grid,
                                        run_policy_figure)
from repro.studies.bus.policies import semantics_folders
from repro.studies.kit.options import Command, Folders

VARIANTS = pictures.VARIANTS
"""Options that choose the picture's panels and the corridor's semantics, not their settings (read
by the command line)."""


def plot(arrivals: pd.DataFrame, stem, all_buses: bool, sources: list[Path]) -> None:
    """One panel per policy of ``arrivals`` (drawn from the CSVs ``sources``)."""
    names = list(dict.fromkeys(arrivals.policy))
    fig, axes = policy_grid(names, "Arrival times at the ten stops", all_buses)
    for ax, name in zip(axes, names):
        sel = arrivals[(arrivals.policy == name) & (all_buses | (arrivals.bus <= BUS_BUSES_DRAWN))]
        for bus, grp in sel.groupby("bus"):
            ax.plot(grp.time_min, grp.stop, "o", ms=1.3, mew=0, label=f"Bus {bus}")
        ax.set_yticks(range(1, 11))
        ax.set_ylim(0.5, 13.2)  # room for the legend above Stop 10
    for ax in axes[-2:]:
        ax.set_xlabel("Time [min]", fontsize=6.5, labelpad=1)
    for ax in axes[::2]:
        ax.set_ylabel("Stop", fontsize=6.5, labelpad=1)
    axes[0].legend(fontsize=5, loc="upper center", ncol=3, markerscale=2.5,
                   handletextpad=0.05, columnspacing=0.6, borderpad=0.3, labelspacing=0.2,
                   framealpha=0.9)
    save_figure(fig, stem, sources)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_policy_arguments(p)


configure = pictures.configure


def run(cmd: Command[PictureConfig], folders: Folders) -> int:
    return run_policy_figure(cmd, semantics_folders(folders, cmd.study.bus),
                             command="fig-bus-arrivals", csv_name="bus_arrivals.csv",
                             table_of=lambda arrivals: arrivals, plot_table=plot)
