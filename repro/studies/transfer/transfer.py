"""Policy transfer from fixed-step to event-driven simulation (paper Fig. "transferperformance",
claims C8 and C9; docs/semantics.md section 6.2).

Policies are trained from scratch (PS-TRPO + M-GAE, ``repro.learn``) on each training simulator: ED,
FS-dT for the paper's five dT values, and FS-1 with T_health = 2.9999. Every trained policy is then
tested on the ED simulator with T_health = 3.0: its ADR (docs/semantics.md section 6.1) over
``test_episodes`` episodes. All policies see the same test episodes (one environment seed), so
differences between them are not test-episode noise; each policy samples its actions from its own
generator.

The paper averages the test ADR of the last epochs' policies; we test each run's final policy (the
one its checkpoint holds) on many episodes, which estimates the same quantity once training has
reached its asymptote (the per-run ``train_adr_last`` column shows the training-curve plateau).

Per simulator the summary gives the mean over the trained policies with its standard error (the
paper's error bars), the IQM, and a bootstrap CI of the mean (``repro.runs.stats``).

``--sampler released-pool`` trains on the released runner's unseeded pool, as the paper's transfer
runs were (:mod:`repro.learn.pool`; files ``*_pool*``, run folders under ``transfer-*-pool``).

``--corrected`` trains and tests with quirks Q1-Q6 switched off (the paper's prose) and writes
``transfer_corrected*.csv`` and ``figures/transfer_corrected.*`` instead; a quirk's flag, as
``train`` spells it (``--no-quirk-q3-unclamped-health``; the old ``--no-quirk q3`` too), switches
one quirk off (``transfer_no_q3*``), ``--no-fire-out-first`` reverses the same-instant order of a
macro-action's end and a fire's extinguishing (``*_no_fire_out_first``; claim X4).

Training runs are checkpointed under ``--runs-dir``/transfer[-corrected]/<scale>/; re-running
skips finished runs and resumes interrupted ones (``repro.studies.kit.sweep``).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
import pandas as pd

from repro.core.config import add_config_arguments, given_fields
from repro.envs.wildfire import QUIRKS, WildfireConfig
from repro.learn.config import learner_label
from repro.runs.provenance import provenance
from repro.runs.results import save_figure, write_result
from repro.studies.kit.options import Command, Folders, add_replot, replot_pair
from repro.studies.transfer.study import (SEMANTICS, TransferConfig, add_size_arguments,
                                          batch_label, fs_label, make_jobs, recorded_config,
                                          study_config, summarise, train_and_test)


def plot(per_policy: pd.DataFrame, summary: pd.DataFrame, stem: Path, title: str,
         sources: list[Path]) -> None:
    """The paper's figure: x = training simulator, y = ADR on ED, error bars = SEM over policies;
    the T_health variant sits at its dT beside the T_health = 3.0 point; the paper's points beside
    ours. ``sources``: the per-policy and summary CSVs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tested = summary.t_health == WildfireConfig.t_health
    main, variant = summary[tested].reset_index(drop=True), summary[~tested]
    xpos = {label: i for i, label in enumerate(main.simulator)}
    for row in variant.itertuples():  # at the FS simulator of the same dT, or after the others
        xpos[row.simulator] = xpos.get(fs_label(row.dt), len(xpos))
    ticks = {**{label: x for label, x in xpos.items() if label in set(main.simulator)},
             **{label: x for label, x in xpos.items() if x >= len(main)}}
    fig, ax = plt.subplots(figsize=(7, 4))
    for frame, marker, color, name in ((main, "o", "C0", "ours"),
                                       (variant, "s", "C3", "ours")):
        x = np.array([xpos[s] for s in frame.simulator], dtype=float)
        for label in frame.simulator:
            dots = per_policy[per_policy.simulator == label].adr_ed
            ax.plot(np.full(len(dots), xpos[label] - 0.12), dots, ".", color=color, alpha=0.4,
                    ms=4)
        th = frame.t_health.iloc[0] if len(frame) else 0
        ax.errorbar(x - 0.06, frame["mean"], yerr=frame["sem"], fmt=marker, color=color,
                    capsize=3, label=f"{name}, T_health = {th:g} (dots: each policy)")
        ax.errorbar(x + 0.06, frame.paper_mean, yerr=frame.paper_sem, fmt=marker, mfc="none",
                    color=color, alpha=0.7, capsize=3, label=f"paper, T_health = {th:g}")
    ax.set_xticks(list(ticks.values()), list(ticks))
    ax.set_xlabel("training simulator")
    ax.set_ylabel("ADR on ED (T_health = 3.0)\nmean over policies, error bars: standard error",
                  fontsize=9)
    ax.set_title(title, fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    save_figure(fig, stem, sources)


VARIANTS = ("corrected", "quirks_off", *QUIRKS, "sim_version", "fire_out_first", "sampler")
"""Options that choose the study, each writing result files of its own (``transfer_corrected*``,
``*_no_q3*``, ``*_20170422``, ``*_no_fire_out_first``, ``*_pool``), not its settings
(:func:`repro.studies.kit.options.scale_departures`)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_size_arguments(p, "transfer*_suite*")
    # the study's semantics and sampler (each writes files of its own), and the simulators it
    # trains: flags of TransferConfig's fields; each quirk's flag as train spells it too
    # (--no-quirk-q3-unclamped-health switches Q3 off in every simulator of the study)
    add_config_arguments(p, TransferConfig, SEMANTICS)
    add_config_arguments(p, WildfireConfig, QUIRKS)
    add_replot(p)


def configure(args: argparse.Namespace) -> Command[TransferConfig]:
    """The study's settings of :func:`add_arguments`'s options (UsageError if bad)."""
    off = {q.split("_")[1] for q, on in given_fields(args, WildfireConfig).items() if not on}
    given = {q.lower() for q in getattr(args, "quirks_off", ())}
    return Command.of(args, study_config(args, quirks_off=tuple(sorted(off | given)) or None))


def figure_title(cfg: TransferConfig, scale: str) -> str:
    """What the figure of a transfer study says of its runs."""
    semantics = ("quirks Q1-Q6 corrected" if cfg.corrected else
                 f"released semantics, {', '.join(cfg.quirks_off).upper()} off" if cfg.quirks_off
                 else "released semantics (Q1-Q6 on)")
    semantics += "" if cfg.fire_out_first else ", UAV before fire at one instant"
    semantics += ", released pool" if cfg.pool else ""
    return (f"Transfer to ED, {semantics}; {scale} scale: {cfg.seeds} policies x {cfg.epochs} "
            f"epochs x {batch_label(cfg)}, {learner_label(cfg.learner)}, simulator of "
            f"{cfg.sim_version}")


def replot(cfg: TransferConfig, folders: Folders) -> int:
    """``--replot``: the figure of the study ``cfg`` names, from its CSVs and the settings its
    sidecar records."""
    return replot_pair(folders, cfg.name, plot=plot, title=lambda prov: figure_title(
        recorded_config(prov), prov["scale"]))


def run(cmd: Command[TransferConfig], folders: Folders) -> int:
    cfg, scale, seed = cmd.study, folders.scale, cmd.seed
    if cmd.replot:
        return replot(cfg, folders)
    results, figures = folders.open()
    t0 = time.perf_counter()
    per_policy, extra = train_and_test(cfg, folders, make_jobs(cfg, scale, seed), seed,
                                       cmd.workers)
    summary = summarise(per_policy, cfg.n_boot, seed)
    prov = provenance(dataclasses.asdict(cfg), command="fig-transfer", scale=scale, seed=seed,
                      wall_seconds=time.perf_counter() - t0, extra=extra)
    sources = [write_result(results / f"{cfg.name}.csv", per_policy, prov),
               write_result(results / f"{cfg.name}_summary.csv", summary, prov)]
    plot(per_policy, summary, figures / cfg.name, figure_title(cfg, scale), sources)
    print(summary[["simulator", "n_policies", "mean", "sem", "ci_low", "ci_high",
                   "paper_mean"]].to_string(index=False))
    return 0
