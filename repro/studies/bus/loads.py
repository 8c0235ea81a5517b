"""Load at arrival of the buses at the records the paper's load figure shows (Fig. bbload; C4,
C5): a 6 h episode, each bus's stop-visit records 40..50 (Stop 10 of its 4th cycle, Stops 1-10 of
its 5th; plotdata.jl), one panel per policy, the paper's five series as black markers beside
ours (buses 1-5; ``--all-buses`` adds Bus 6, which the paper did not draw).

Writes results/bus_load.csv (source: paper or ours, policy, bus, record, stop, load; the paper's
rows of a policy are the panel it is compared with: the thresholds panel for both thresholds
policies) and figures/bus_load; and results/bus_load_switches.csv: for No Holding and the
authors' thresholds (fixed policies, so the corridor alone decides), the L1 distance per point to
the paper's panel with each of B1-B5 turned off alone (``off``: none, a switch, or all); and,
with the MLP panel taken from the lambda sweep, results/bus_load_mlp_runs.csv: every trained run
of that sweep (lambda, seed, final return), acting greedily, with its L1 distance per point to the
paper's MLP panel. The GRU panels (``--policies ... gru gru-greedy``: the arrival figure's) are
compared with the paper's MLP panel too, which the released GRU drew. The figure is one column
wide, the panels two by two; ``--replot`` draws it again from results/bus_load.csv (and writes
nothing else).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import pandas as pd

from repro.envs.bus import BusConfig
from repro.envs.bus.metrics import l1_per_point, record_loads
from repro.envs.bus.params import SWITCHES
from repro.learn.config import DEFAULT_LEARNER
from repro.paper import BUS_BUSES_DRAWN, PAPER_RECORDS, PAPER_STOPS, paper_loads
from repro.runs.provenance import provenance
from repro.runs.results import read_result, save_figure, write_result
from repro.studies.bus import pictures
from repro.studies.bus.pictures import (PictureConfig, add_policy_arguments, learner_csv,
                                        policy_grid, run_policy_figure)
from repro.studies.bus.policies import (TrainedPolicy, lambda_summary_csv, make_policy,
                                        picture_arrivals, semantics_folders)
from repro.studies.kit.options import Command, Folders

VARIANTS = pictures.VARIANTS
"""Options that choose the picture's panels and the corridor's semantics, not their settings (read
by the command line)."""

LOAD_CSV = "bus_load.csv"
SWITCHES_CSV = "bus_load_switches.csv"
MLP_RUNS_CSV = "bus_load_mlp_runs.csv"
COLUMNS = ["source", "policy", "bus", "record", "stop", "load"]
FIXED = ("nohold", "authors")
"""The policies whose panel depends on the corridor alone."""


def switch_distances(cfg: BusConfig, policies: list[str]) -> pd.DataFrame:
    """Rows policy, off, l1_per_point: ``cfg``, then each switch off alone, then all off."""
    variants = {"none": cfg, **{name: dataclasses.replace(cfg, **{name: False})
                                for name in SWITCHES}, "all": BusConfig.corrected()}
    rows = []
    for name in policies:
        for off, c in variants.items():
            arrivals = picture_arrivals(make_policy(name, c), c).assign(policy=name)
            rows.append(dict(policy=name, off=off, l1_per_point=l1_per_point(loads(arrivals))))
    return pd.DataFrame(rows)


def loads(arrivals: pd.DataFrame) -> pd.DataFrame:
    frames = []
    for name, grp in arrivals.groupby("policy", sort=False):
        frames.append(paper_loads(name).assign(source="paper", policy=name))
        frames.append(record_loads(grp).assign(source="ours", policy=name))
    return pd.concat(frames, ignore_index=True)[COLUMNS]


def plot(table: pd.DataFrame, stem, all_buses: bool, sources: list[Path]) -> None:
    """One panel per policy of ``table`` (drawn from the CSVs ``sources``)."""
    names = list(dict.fromkeys(table.policy))
    fig, axes = policy_grid(names, "Load at arrival, records 40-50 (Stop 10 of cycle 4, "
                            "cycle 5)", all_buses)
    for ax, name in zip(axes, names):
        sel = table[table.policy == name]
        for bus, grp in sel[sel.source == "ours"].groupby("bus"):
            if all_buses or bus <= BUS_BUSES_DRAWN:
                ax.plot(grp.record, grp.load, ".-", ms=2, lw=0.6, label=f"Bus {bus}")
        paper = sel[sel.source == "paper"]
        ax.plot(paper.record, paper.load, "o", mfc="none", mec="k", ms=3.5, mew=0.5, lw=0,
                label="paper")
        ax.axhline(BusConfig().l_max, color="k", lw=0.6, ls="--")
        ax.set_ylim(-3, 1.3 * BusConfig().l_max)  # room for the legend above the capacity
        ax.set_xticks(PAPER_RECORDS, [str(k) for k in PAPER_STOPS])
    for ax in axes[-2:]:
        ax.set_xlabel("Stop", fontsize=6.5, labelpad=1)
    for ax in axes[::2]:
        ax.set_ylabel("Load at arrival [pax]", fontsize=6.5, labelpad=1)
    axes[0].legend(fontsize=5, loc="upper center", ncol=3, handlelength=1.2, handletextpad=0.3,
                   columnspacing=0.6, borderpad=0.3, labelspacing=0.2, framealpha=0.9)
    save_figure(fig, stem, sources)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_policy_arguments(p)


def mlp_run_distances(cfg: BusConfig, results: Path, learner: str | None) -> pd.DataFrame:
    """Rows lambda, seed, final_return, run, l1_per_point: each run of ``learner``'s lambda
    sweep."""
    runs = read_result(results / lambda_summary_csv(learner))
    rows = []
    for lam, ret, run in runs[runs.policy == "mlp-run"][["lambda", "final_iqm", "run"]].values:
        arrivals = picture_arrivals(TrainedPolicy(run, cfg), cfg).assign(policy="mlp")
        rows.append({"lambda": lam, "seed": int(Path(run).name.split("seed")[-1]),
                     "final_return": ret, "run": run,
                     "l1_per_point": l1_per_point(loads(arrivals))})
    return pd.DataFrame(rows)


configure = pictures.configure


def run(cmd: Command[PictureConfig], folders: Folders) -> int:
    folders = semantics_folders(folders, cmd.study.bus)
    rc = run_policy_figure(cmd, folders, command="fig-bus-load", csv_name=LOAD_CSV, table_of=loads,
                           plot_table=plot)
    if cmd.replot:
        return rc
    cfg, learner = cmd.study, cmd.study.sources.learner
    fixed = [p for p in cfg.policies if p in FIXED]
    if fixed:
        t0 = time.perf_counter()
        table = switch_distances(cfg.bus, fixed)
        prov = provenance(cfg.bus, command="fig-bus-load", scale=folders.scale, seed=None,
                          wall_seconds=time.perf_counter() - t0)
        write_result(folders.results / SWITCHES_CSV, table, prov)
    if "mlp" in cfg.policies and cfg.sources.mlp_run is None:
        t0 = time.perf_counter()
        table = mlp_run_distances(cfg.bus, folders.results, learner)
        prov = provenance(cfg.bus, command="fig-bus-load", scale=folders.scale, seed=None,
                          wall_seconds=time.perf_counter() - t0,
                          extra={"learner": learner or DEFAULT_LEARNER})
        write_result(folders.results / learner_csv(MLP_RUNS_CSV, learner), table, prov)
    return rc
