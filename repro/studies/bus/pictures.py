"""What the bus pictures (``bus-arrivals``, ``bus-loads``) share: their options, one episode per
policy, a panel per policy, and the body of their run."""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path
from typing import Callable

import pandas as pd

from repro.core.errors import refuse_unused, require
from repro.envs.bus import add_switch_arguments, config_from_args
from repro.envs.bus.params import BusConfig
from repro.learn.config import DEFAULT_LEARNER, add_learner_option, learner_stem
from repro.paper import BUS_BUSES_DRAWN
from repro.runs.provenance import provenance
from repro.runs.results import write_result
from repro.studies.bus.gru_runs import best_gru_run
from repro.studies.bus.policies import (BUS_VARIANTS, DEFAULT_PANELS, GRU_PANELS, POLICIES,
                                        PolicySources, best_run, picture_arrivals)
from repro.studies.kit.options import (Command, Folders, add_common, add_replot, read_for_replot,
                                       replot_figures)
from repro.studies.kit.sweep import add_sweep_arguments


VARIANTS = ("policies", *BUS_VARIANTS)
"""The options that choose which panels a picture holds (each panel's episode is the same
whichever others are drawn) and the corridor's semantics, not its settings
(:func:`repro.studies.kit.options.scale_departures`)."""

TITLES = {"nohold": "No Holding", "mlp": "Optimized MLP Policy",
          "authors": "Authors' Thresholds", "thresholds": "Optimized Thresholds (ours)",
          "gru": "Optimized GRU (sampled)", "gru-greedy": "Optimized GRU (greedy)"}


def add_policy_arguments(p: argparse.ArgumentParser) -> None:
    """The options both bus figure drivers share."""
    add_common(p, seed=None)
    p.add_argument("--policies", nargs="+", default=list(DEFAULT_PANELS),
                   help="panels, in order, of " + ", ".join(POLICIES) + " (default: "
                   + " ".join(DEFAULT_PANELS) + "; gru and gru-greedy: the released GRU policy "
                   "that drew the paper's pictures, sampled and greedy)")
    p.add_argument("--thresholds", type=float, nargs=3, metavar=("T1", "T2", "T3"),
                   help="our thresholds in seconds (default: results/bus_thresholds.csv)")
    p.add_argument("--mlp-run", help="training run folder of the mlp panel, acting greedily "
                   "(default: the lambda sweep's best run, from results/bus_lambda_summary.csv)")
    add_learner_option(p, "<figure>_suite*; the mlp panel is then the suite learner's best run")
    p.add_argument("--gru-run", help="training run folder of the gru panels (default: the best "
                   "by test return of the GRU runs in --runs-dir, trained first where they are "
                   "not finished; results/bus_gru_runs.csv lists them)")
    add_sweep_arguments(p)
    p.add_argument("--all-buses", action="store_true",
                   help="draw all six buses (the paper drew buses 1-5)")
    add_replot(p)
    add_switch_arguments(p)


@dataclasses.dataclass(frozen=True)
class PictureConfig:
    """A bus picture's settings: its panels, where their policies come from, the corridor."""

    policies: tuple[str, ...]
    """The panels, in order (``--policies``)."""
    sources: PolicySources
    """Where the panels' policies come from (``--thresholds``, ``--mlp-run``, ``--gru-run``,
    ``--learner``)."""
    all_buses: bool
    """Draw all six buses, not the paper's buses 1-5 (``--all-buses``)."""
    bus: BusConfig
    """The corridor, its switches B1-B5 as given."""


def configure(args: argparse.Namespace) -> Command[PictureConfig]:
    """The picture's settings of :func:`add_policy_arguments`'s options, checked before any work:
    the panels' names, and no option of a panel not drawn (:func:`check_panel_options`)."""
    for name in args.policies:
        require(name in POLICIES, "--policies", "names from " + ", ".join(POLICIES), name)
    check_panel_options(args)
    return Command.of(args, PictureConfig(
        policies=tuple(args.policies), sources=PolicySources.of(args),
        all_buses=args.all_buses, bus=config_from_args(args)))


def learner_csv(csv_name: str, learner: str | None) -> str:
    """A bus figure's CSV for ``learner``'s mlp panel: ``csv_name``, its stem then ``_suite`` for
    the suite learner's."""
    return learner_stem(Path(csv_name).stem, learner or DEFAULT_LEARNER) + ".csv"


def mlp_source(cfg: PictureConfig, folders: Folders) -> str | None:
    """The run folder the mlp panel comes from (None without an mlp panel), for the provenance."""
    if "mlp" not in cfg.policies:
        return None
    return str(cfg.sources.mlp_run if cfg.sources.mlp_run is not None
               else best_run(folders.results, learner=cfg.sources.learner))


def gru_source(cmd: Command[PictureConfig], folders: Folders) -> str | None:
    """The run folder the gru panels come from (None without a gru panel): --gru-run, else the
    best of the GRU runs, trained here where they are not finished
    (:func:`repro.studies.bus.gru_runs.best_gru_run`)."""
    cfg = cmd.study
    if not set(GRU_PANELS) & set(cfg.policies):
        return None
    return str(cfg.sources.gru_run if cfg.sources.gru_run is not None
               else best_gru_run(folders, cfg.bus, cmd.workers))


def collect(cfg: PictureConfig, results: Path) -> pd.DataFrame:
    """One episode per policy (all are deterministic): its arrival table, tagged with the policy.
    Every policy is built before any is run, so bad input fails before any work."""
    policies = {name: cfg.sources.policy(name, cfg.bus, results) for name in cfg.policies}
    frames = []
    for name, policy in policies.items():
        arrivals = picture_arrivals(policy, cfg.bus)
        frames.append(arrivals.drop(columns="episode").assign(policy=name))
    cols = ["policy"] + [c for c in frames[0].columns if c != "policy"]
    return pd.concat(frames, ignore_index=True)[cols]


COLUMN_WIDTH = 3.5
"""Inches: one column of a two-column paper, the width the bus figures are drawn at."""


def policy_grid(names: list[str], what: str, all_buses: bool):
    """A figure of one column's width with a panel per policy, two by two, and a title that says
    which buses are drawn (the paper drew buses 1-5; ``--all-buses`` adds Bus 6): the figure,
    and the axes in the panels' order (the unused ones hidden)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = -(-len(names) // 2)
    cols = min(2, len(names))
    fig, axes = plt.subplots(rows, cols, figsize=(COLUMN_WIDTH, 0.6 + 1.75 * rows), sharex=True,
                             sharey=True, squeeze=False)
    buses = (f"all six buses (the paper drew buses 1-{BUS_BUSES_DRAWN})" if all_buses else
             f"buses 1-{BUS_BUSES_DRAWN}, as the paper drew them (Bus 6 not drawn)")
    fig.suptitle(f"{what}, one 6 h episode per policy;\n{buses}", fontsize=6.5)
    flat = list(axes.flat)
    for ax in flat[len(names):]:
        ax.set_visible(False)
        flat[flat.index(ax) - cols].tick_params(labelbottom=True)  # the panel above is the last
    for ax, name in zip(flat, names):
        ax.set_title(TITLES.get(name, name), fontsize=7, pad=2)
        ax.tick_params(labelsize=6, length=2, pad=1)
        ax.grid(True, alpha=0.3)
    return fig, flat[:len(names)]


def check_panel_options(args: argparse.Namespace) -> None:
    """Refuse the options of a panel that ``--policies`` does not draw, and the sweep's options
    where no gru run is trained (a gru panel without --gru-run trains them)."""
    gru = bool(set(GRU_PANELS) & set(args.policies))
    trains = gru and args.gru_run is None
    training = "where the gru panels' runs are trained (a gru panel without --gru-run)"
    refuse_unused(
        ("--thresholds", args.thresholds, "thresholds" in args.policies,
         "with a thresholds panel (--policies ... thresholds)"),
        ("--mlp-run", args.mlp_run, "mlp" in args.policies,
         "with an mlp panel (--policies ... mlp)"),
        ("--gru-run", args.gru_run, gru, "with a gru panel (--policies gru or gru-greedy)"),
        ("--n-jobs", args.n_jobs, trains, training),
        ("--scheduler", args.scheduler, trains, training))


def run_policy_figure(cmd: Command[PictureConfig], folders: Folders, *, command: str,
                      csv_name: str, table_of: Callable[[pd.DataFrame], pd.DataFrame],
                      plot_table: Callable[[pd.DataFrame, Path, bool, list[Path]], None]) -> int:
    """Shared body of the per-policy bus figures: simulate each policy's episode, derive the
    figure's table from the arrival records, write it with provenance, and draw it; with
    ``--replot``, draw the table written before (the panels of ``--policies``)."""
    cfg = cmd.study
    csv_name = learner_csv(csv_name, cfg.sources.learner)
    stem = folders.figures / Path(csv_name).stem
    if cmd.replot:
        table, = read_for_replot(folders, csv_name)
        _, sources = replot_figures(folders, csv_name)
        plot_table(table[table.policy.isin(cfg.policies)], stem, cfg.all_buses, sources)
        print(f"wrote {stem}.png/.pdf")
        return 0
    folders.open_figures()
    results = folders.open_results()
    t0 = time.perf_counter()
    # the panels and the provenance name the gru run chosen
    cfg = dataclasses.replace(cfg, sources=dataclasses.replace(
        cfg.sources, gru_run=gru_source(cmd, folders)))
    table = table_of(collect(cfg, results))
    prov = provenance(cfg.bus, command=command, scale=folders.scale, seed=None,
                      wall_seconds=time.perf_counter() - t0,
                      extra={"policies": list(cfg.policies), "mlp_run": mlp_source(cfg, folders),
                             "gru_run": cfg.sources.gru_run,
                             "learner": cfg.sources.learner or DEFAULT_LEARNER})
    plot_table(table, stem, cfg.all_buses, [write_result(results / csv_name, table, prov)])
    print(f"wrote {results / csv_name} and {stem}.png/.pdf")
    return 0
