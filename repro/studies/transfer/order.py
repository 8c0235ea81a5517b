"""Does C9 depend on the same-instant order? (claim X4, beyond the paper; docs/semantics.md
sections 3.9 and 6.12)

C9's mechanism is an FS-1 coincidence: with T_health = 2.9999 a fire goes out at the very grid
instant at which the hold that put it out ends. Which comes first at that instant, the fire's
extinguishing or the UAV's observation, is the same-instant order (``fire_out_first``: the
released code puts the fire first). This driver runs C9's pair, FS-1 trained with T_health 3.0
and 2.9999 and tested on ED, under the released order and reversed, on the released semantics
(where C9 does not reproduce) and on them with Q3 off (where it does): 2 semantics x 2 orders x
2 T_health x ``seeds`` policies.

Each (semantics, order) is a transfer study (:mod:`repro.studies.transfer.study`) restricted to
the pair, trained and tested as there, in its own run folders. So the released-order runs are
those of ``fig-transfer`` and ``fig-transfer --no-quirk-q3-unclamped-health`` (a sweep skips
finished runs), and the reversed ones are those of ``fig-transfer
[--no-quirk-q3-unclamped-health] --no-fire-out-first``. With Q3 off the numbers are those of
``fig-transfer --no-quirk-q3-unclamped-health --simulator FS-1 --simulator "FS-1
(T_health=2.9999)"``; with Q3 on, the same policies as the full study's, but each samples its test
actions from another stream (a policy's stream is its place in its study), so its ADR differs from
``transfer.csv``'s within the noise.

Outputs: ``order_reversal.csv`` (one row per policy), ``order_reversal_summary.csv`` (per
semantics, order and simulator, as the transfer summary), ``order_reversal_effect.csv`` (per
semantics and order: the mean ADR with T_health 2.9999 minus that with 3.0, its 95% stratified
bootstrap CI, and whether the CI lies below 0), and ``figures/<scale>/order_reversal``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
import pandas as pd

from repro.learn.config import learner_label, learner_stem
from repro.runs.provenance import provenance
from repro.runs.results import save_figure, write_result
from repro.studies.kit.options import Command, Folders, add_replot, replot_pair
from repro.studies.kit.sweep import run_sweeps
from repro.studies.transfer.study import (TransferConfig, add_size_arguments, batch_label, effects,
                                          make_jobs, recorded_config, runs_folder, study_config,
                                          summarise, train_and_test)

NAME = "order_reversal"
"""Stem of the result files and the figure."""
SEMANTICS = {"released": (), "released, Q3 off": ("q3",)}
"""Semantics of the study: the quirks switched off."""
ORDERS = {"released": True, "reversed": False}
"""Same-instant orders: ``fire_out_first``."""


def studies(base: TransferConfig) -> list[tuple[str, str, TransferConfig]]:
    """(semantics, order, transfer study of C9's pair) for every semantics and order."""
    return [(semantics, order, dataclasses.replace(base, quirks_off=off, fire_out_first=first,
                                                   only=base.variant_pair()))
            for semantics, off in SEMANTICS.items() for order, first in ORDERS.items()]


def plot(per_policy: pd.DataFrame, summary: pd.DataFrame, stem: Path, title: str,
         sources: list[Path]) -> None:
    """ADR on ED per semantics and order: T_health 3.0 and 2.9999 side by side, mean with its
    bootstrap CI, each policy a dot; ``sources``: the per-policy and summary CSVs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = list(dict.fromkeys(zip(summary.semantics, summary.order)))
    fig, ax = plt.subplots(figsize=(7, 4))
    for k, (label, color, shift) in enumerate(zip(summary.simulator.unique(), ("C0", "C3"),
                                                  (-0.1, 0.1))):
        for x, (semantics, order) in enumerate(groups):
            at = ((summary.semantics == semantics) & (summary.order == order)
                  & (summary.simulator == label))
            row = summary[at].iloc[0]
            dots = per_policy[(per_policy.semantics == semantics) & (per_policy.order == order)
                              & (per_policy.simulator == label)].adr_ed
            ax.plot(np.full(len(dots), x + 2 * shift), dots, ".", color=color, alpha=0.4, ms=4)
            ax.errorbar(x + shift, row["mean"], yerr=[[row["mean"] - row.ci_low],
                                                      [row.ci_high - row["mean"]]],
                        fmt="os"[k], color=color, capsize=3, label=label if x == 0 else None)
    ax.set_xticks(range(len(groups)), [f"{s}\n{o} order" for s, o in groups], fontsize=8)
    ax.set_ylabel("ADR on ED (T_health = 3.0)\nmean over policies, error bars: 95% bootstrap "
                  "CI", fontsize=8)
    ax.set_title(title, fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    save_figure(fig, stem, sources)


def title(base: TransferConfig, scale: str) -> str:
    """The figure's title: the study's sizes at ``scale`` and its learner."""
    return (f"C9's pair under both same-instant orders; {scale} scale: {base.seeds} policies x "
            f"{base.epochs} epochs x {batch_label(base)}, {learner_label(base.learner)}")


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_size_arguments(p, "order_reversal_suite*")
    add_replot(p)


def replot(base: TransferConfig, folders: Folders) -> int:
    """``--replot``: the figure of ``base``'s learner from its CSVs, titled with the settings
    their sidecar records."""
    return replot_pair(folders, learner_stem(NAME, base.learner), plot=plot,
                       title=lambda prov: title(recorded_config(prov), prov["scale"]))


def configure(args: argparse.Namespace) -> Command[TransferConfig]:
    # the transfer study's sizes at every scale, so that the released-order runs are its own
    return Command.of(args, study_config(args))


def run(cmd: Command[TransferConfig], folders: Folders) -> int:
    base, scale, seed = cmd.study, folders.scale, cmd.seed
    if cmd.replot:
        return replot(base, folders)
    results, figures = folders.open()
    plan = [(semantics, order, cfg, runs_folder(folders, cfg))
            for semantics, order, cfg in studies(base)]
    t0 = time.perf_counter()
    # every study's runs in one pool (each study's folders checked before any trains)
    run_sweeps([([job for _, job in make_jobs(cfg, scale, seed)], runs)
                for _, _, cfg, runs in plan], cmd.workers)
    per_policy, summary = [], []
    for semantics, order, cfg, _ in plan:
        tested, _ = train_and_test(cfg, folders, make_jobs(cfg, scale, seed), seed, cmd.workers)
        for frame, out in ((tested, per_policy), (summarise(tested, cfg.n_boot, seed),
                                                  summary)):
            out.append(frame.assign(semantics=semantics, order=order)[
                ["semantics", "order", *frame.columns]])
    per_policy, summary = pd.concat(per_policy, ignore_index=True), pd.concat(summary,
                                                                             ignore_index=True)
    effect = effects(per_policy, base.variant_pair(), base.n_boot, seed)
    stem = learner_stem(NAME, base.learner)
    config = dict(dataclasses.asdict(base), studies=[cfg.name for _, _, cfg, _ in plan])
    prov = provenance(config, command="beyond-order", scale=scale, seed=seed,
                      wall_seconds=time.perf_counter() - t0,
                      extra=dict(runs_dirs=[str(runs) for *_, runs in plan]))
    sources = [write_result(results / f"{stem}.csv", per_policy, prov),
               write_result(results / f"{stem}_summary.csv", summary, prov)]
    write_result(results / f"{stem}_effect.csv", effect, prov)
    plot(per_policy, summary, figures / stem, title(base, scale), sources)
    print(effect.to_string(index=False))
    return 0
