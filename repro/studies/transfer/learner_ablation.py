"""Which learner settings the transfer figure depends on (paper Fig. "transferperformance";
docs/semantics.md section 6.13; claim X5).

From the authors' learner on the simulator the figure was trained on (2017-04-22), one setting at a
time is changed to the suite's (:data:`ROWS`): observation normalisation, two hidden layers,
orthogonal initialisation, batches counted in episodes, a fifth of the decisions for the Fisher
products, the crowding penalty of the released HEAD (20), and every departure at once (the suite's
learner). Each row is a transfer study (:mod:`repro.studies.transfer.transfer`) restricted to the
simulators asked for, in that study's run folders: the "authors" row is ``fig-transfer
--sim-version 2017-04-22``'s runs and the "crowding penalty 20" row ``fig-transfer``'s. Every
policy is tested on ED under both protocols (the final policy on ``test_episodes`` episodes, and
the released runner's mean over the last 40 epochs' policies).

Outputs: ``learner_ablation.csv`` (one row per policy), ``learner_ablation_summary.csv`` (per
setting and simulator, as the transfer summary, with the paper's point and the distance to it in
standard errors), ``learner_ablation_c9.csv`` (per setting and protocol: C9's degradation, the
mean ADR of FS-1 with T_health 2.9999 minus that of FS-1, with its 95% stratified bootstrap CI;
claim X5), and ``figures/<scale>/learner_ablation``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from repro.core.config import add_config_arguments
from repro.envs.wildfire import FIGURE_VERSION, RELEASED_VERSION
from repro.learn.config import learner_stem
from repro.runs.provenance import provenance
from repro.runs.results import read_provenance, save_figure, write_result
from repro.studies.kit.options import Command, Folders, add_replot, read_for_replot, replot_figures
from repro.studies.kit.sweep import run_sweeps
from repro.studies.transfer.study import (TransferConfig, add_size_arguments, batch_label, effects,
                                          make_jobs, recorded_config, runs_folder, study_config,
                                          summarise, train_and_test)

NAME = "learner_ablation"
"""Stem of the result files and the figure."""
DEFAULT_SIMULATORS = ("ED", "FS-1", "FS-1 (T_health=2.9999)")
"""The training simulators of a row unless asked otherwise: ED and the pair of C9."""
_EFFECT_STREAM = 5
"""Child of the root seed for the C9 effects' bootstrap (beyond-order uses 4)."""


def rows(base: TransferConfig) -> dict[str, dict[str, Any]]:
    """Each row's TransferConfig fields: the authors' set-up, then one departure at a time."""
    authors = dict(learner="authors", settings=(), sim_version=FIGURE_VERSION)
    one = {"observation normalisation": (("normalize_obs", True),),
           "two hidden layers": (("hidden", (32, 32)),),
           "orthogonal init": (("init", "orthogonal"),),
           "batch in episodes": (("batch_episodes", base.batch_episodes),),
           "Fisher subsample 0.2": (("fvp_subsample", 0.2),)}
    return {"authors": authors,
            **{name: dict(authors, settings=settings) for name, settings in one.items()},
            "crowding penalty 20": dict(authors, sim_version=RELEASED_VERSION),
            "suite (all departures)": dict(authors, learner="suite")}


def studies(base: TransferConfig) -> list[tuple[str, TransferConfig]]:
    """(row, transfer study restricted to the base's simulators) for every row."""
    return [(name, dataclasses.replace(base, **fields)) for name, fields in rows(base).items()]


def plot(summary: pd.DataFrame, stem: Path, title: str, sources: list[Path]) -> None:
    """ADR on ED per row and training simulator (mean and SEM over policies), the paper's points
    as dashed lines; ``sources``: the summary's CSV."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    settings = list(dict.fromkeys(summary.setting))
    sims = list(dict.fromkeys(summary.simulator))
    fig, ax = plt.subplots(figsize=(8, 4.2))
    width = 0.8 / len(sims)
    for k, sim in enumerate(sims):
        g = summary[summary.simulator == sim].set_index("setting").reindex(settings)
        x = np.arange(len(settings)) - 0.4 + (k + 0.5) * width
        ax.errorbar(x, g["mean"], yerr=g["sem"], fmt="o", ms=4, capsize=2, color=f"C{k}",
                    label=sim)
        ax.axhline(g.paper_mean.iloc[0], color=f"C{k}", ls="--", lw=0.8, alpha=0.7)
    ax.set_xticks(range(len(settings)), settings, rotation=20, ha="right", fontsize=7)
    ax.set_ylabel("ADR on ED (T_health = 3.0)\nmean over policies, error bars: standard error",
                  fontsize=8)
    ax.set_title(title, fontsize=8)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, title="trained on (dashed: paper)", title_fontsize=7)
    save_figure(fig, stem, sources)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_size_arguments(p, "learner_ablation_suite*")
    add_config_arguments(p, TransferConfig, ("only",), defaults=dict(only=DEFAULT_SIMULATORS))
    add_replot(p)


def title(base: TransferConfig, scale: str) -> str:
    """The figure's title: the study's sizes at ``scale``."""
    return (f"One learner setting at a time from the authors' (simulator of {FIGURE_VERSION}); "
            f"{scale} scale: {base.seeds} policies x {base.epochs} epochs x {batch_label(base)}")


def replot(base: TransferConfig, folders: Folders) -> int:
    """``--replot``: the figure of ``base``'s learner from its summary CSV, titled with the
    settings its sidecar records."""
    stem = learner_stem(NAME, base.learner)
    summary, = read_for_replot(folders, f"{stem}_summary.csv")
    prov = read_provenance(folders.results / f"{stem}_summary.csv")
    figures, sources = replot_figures(folders, f"{stem}_summary.csv")
    out = figures / stem
    plot(summary, out, title(recorded_config(prov), prov["scale"]), sources)
    print(f"wrote {out}.png/.pdf")
    return 0


def configure(args: argparse.Namespace) -> Command[TransferConfig]:
    return Command.of(args, study_config(args, only=getattr(args, "only", DEFAULT_SIMULATORS)))


def run(cmd: Command[TransferConfig], folders: Folders) -> int:
    base, scale, seed = cmd.study, folders.scale, cmd.seed
    if cmd.replot:
        return replot(base, folders)
    results, figures = folders.open()
    plan = [(name, cfg, runs_folder(folders, cfg))
            for name, cfg in studies(base)]
    t0 = time.perf_counter()
    # every study's runs in one pool (each study's folders checked before any trains)
    run_sweeps([([job for _, job in make_jobs(cfg, scale, seed)], runs)
                for _, cfg, runs in plan], cmd.workers)
    per_policy, summary = [], []
    for name, cfg, _ in plan:
        tested, _ = train_and_test(cfg, folders, make_jobs(cfg, scale, seed), seed, cmd.workers)
        for frame, out in ((tested, per_policy), (summarise(tested, cfg.n_boot, seed),
                                                  summary)):
            out.append(frame.assign(setting=name)[["setting", *frame.columns]])
    per_policy, summary = (pd.concat(per_policy, ignore_index=True),
                           pd.concat(summary, ignore_index=True))
    pair = base.variant_pair()
    c9 = pd.concat([effects(per_policy, pair, base.n_boot, seed, by=("setting",),
                            score=score, stream=_EFFECT_STREAM).assign(protocol=protocol)
                    for protocol, score in (("final policy", "adr_ed"),
                                            ("last 40 policies", "adr_ed_kept"))]
                   if set(pair) <= set(base.only) else [], ignore_index=True)
    config = dict(dataclasses.asdict(base), rows=[cfg.name for _, cfg, _ in plan])
    stem = learner_stem(NAME, base.learner)
    prov = provenance(config, command="learner-ablation", scale=scale, seed=seed,
                      wall_seconds=time.perf_counter() - t0,
                      extra=dict(runs_dirs=[str(runs) for *_, runs in plan]))
    write_result(results / f"{stem}.csv", per_policy, prov)
    sources = [write_result(results / f"{stem}_summary.csv", summary, prov)]
    if len(c9):
        write_result(results / f"{stem}_c9.csv", c9, prov)
    plot(summary, figures / stem, title(base, scale), sources)
    print(summary[["setting", "simulator", "mean", "sem", "mean_kept", "paper_mean",
                   "z_paper"]].to_string(index=False))
    if len(c9):
        print(c9.to_string(index=False))
    return 0
