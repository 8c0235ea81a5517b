"""``python -m repro plot-runs RUN_DIR... [--out FILE]``: the training curves of any run folders.

Each RUN_DIR is a folder that ``train`` (or a study) wrote: its ``progress.csv`` holds one row per
epoch, its ``config.json`` the run's settings. Runs whose settings are equal but for the seed are
one group: a line of their mean per epoch, with a band of the 95% t-interval of that mean across
the group's seeds (over the epochs all of them reached; none with one run). The legend names each
group by the settings in which the groups differ, and its number of runs. ``--metric`` picks the
column (default: average_return for the bus, the paper's measure, else
average_discounted_return, ADR); the figure is PNG or PDF by the suffix of ``--out``, and its
sidecar (``runs.provenance.json`` beside ``runs.png``) names the progress tables it was drawn from,
with their hashes.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from repro.core.errors import UsageError, require

from repro.runs.files import check_writable_dir
from repro.runs.results import FIGURE_FORMATS, save_figure
from repro.runs.run_folder import CONFIG, PROGRESS, PROGRESS_COLUMNS, read_config

METRICS = [c for c in PROGRESS_COLUMNS if c != "epoch"]
"""The progress.csv columns that can be drawn."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("runs", nargs="+", metavar="RUN_DIR", help="run folders of train or a study "
                   f"(each with {PROGRESS} and {CONFIG})")
    p.add_argument("--out", default="runs.png", help="the figure, .png or .pdf (runs.png)")
    p.add_argument("--metric", help="progress.csv column: " + ", ".join(METRICS) + " (bus: "
                   "average_return, else average_discounted_return)")


def setting(config: dict[str, Any]) -> dict[str, Any]:
    """A run's settings but for its seed, flattened: ``env.gamma``, ``train.lam``, ...."""
    flat = {"env_name": config.get("env_name")}
    for part in ("env", "train"):
        for key, value in (config.get(part) or {}).items():
            if key != "seed":
                flat[f"{part}.{key}"] = value
    return flat


def read_runs(folders: list[str]) -> list[tuple[dict[str, Any], pd.DataFrame]]:
    """Every run's settings and progress table (a UsageError for a folder that is not a run)."""
    runs = []
    allowed = f"run folders of train or a study (each with {PROGRESS} and {CONFIG})"
    for name in folders:
        folder = Path(name)
        require((folder / PROGRESS).is_file() and (folder / CONFIG).is_file(), "RUN_DIR",
                allowed, name)
        config = read_config(folder, "RUN_DIR")
        try:
            table = pd.read_csv(folder / PROGRESS)
        except (OSError, ValueError, pd.errors.ParserError):
            raise UsageError("RUN_DIR", allowed + f", a readable {PROGRESS}", name) from None
        require("epoch" in table and len(table) > 0, "RUN_DIR",
                allowed + f", at least one epoch in {PROGRESS}", name)
        runs.append((setting(config), table))
    return runs


def shown(key: str, value: Any) -> str:
    """A setting as a label shows it: ``lam=2.0``; the simulator as the paper names it, ED where
    ``dt`` is None (event-driven) and ``FS-dT`` otherwise."""
    if key == "env.dt":
        return "ED" if value is None else f"FS-{value:g}"
    return f"{key.split('.', 1)[-1]}={value}"


def groups(runs: list[tuple[dict[str, Any], pd.DataFrame]]) -> list[tuple[str, list[pd.DataFrame]]]:
    """The runs grouped by setting, in the order of their first run; each group's label names
    the settings in which the groups differ (the environment if there is one group)."""
    keyed: dict[str, tuple[dict[str, Any], list[pd.DataFrame]]] = {}
    for config, table in runs:
        key = json.dumps(config, sort_keys=True, default=str)
        keyed.setdefault(key, (config, []))[1].append(table)
    configs = [c for c, _ in keyed.values()]
    keys = sorted({k for c in configs for k in c})
    differ = [k for k in keys if len({json.dumps(c.get(k), default=str) for c in configs}) > 1]
    labelled = []
    for config, tables in keyed.values():
        parts = [shown(k, config.get(k)) for k in differ] or [
            str(config["env_name"])]
        labelled.append((", ".join(parts) + f" ({len(tables)} run{'s' * (len(tables) > 1)})",
                         tables))
    return labelled


def curve(tables: list[pd.DataFrame], metric: str) -> pd.DataFrame:
    """Mean of ``metric`` per epoch over the runs, and the 95% t-interval's half width (NaN with
    one run), over the epochs every run reached."""
    from scipy import stats as sps  # here, not above: a command's options are checked without it

    last = min(int(t["epoch"].max()) for t in tables)
    values = np.stack([t.set_index("epoch")[metric].loc[:last].to_numpy(float) for t in tables])
    n = len(tables)
    half = (values.std(axis=0, ddof=1) / np.sqrt(n) * sps.t.ppf(0.975, n - 1) if n > 1
            else np.full(values.shape[1], np.nan))
    return pd.DataFrame({"epoch": np.arange(values.shape[1]), "mean": values.mean(axis=0),
                         "half": half})


def plot(labelled: list[tuple[str, list[pd.DataFrame]]], metric: str, env_name: str,
         out: Path, sources: list[Path]) -> None:
    """Draw the groups' curves into ``out``, with a sidecar naming the progress tables
    ``sources`` (:func:`repro.runs.results.save_figure`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(3.5, 2.6))  # one column of a paper
    for label, tables in labelled:
        c = curve(tables, metric)
        line, = ax.plot(c["epoch"], c["mean"], lw=1.2, label=label)
        if len(tables) > 1:
            ax.fill_between(c["epoch"], c["mean"] - c["half"], c["mean"] + c["half"],
                            color=line.get_color(), alpha=0.2)
    ax.set_xlabel("Epoch", fontsize=8)
    ax.set_ylabel(f"{metric.replace('_', ' ')}\n(mean over seeds, 95% t-interval)", fontsize=8)
    ax.set_title(f"{env_name} training runs", fontsize=9)
    ax.tick_params(labelsize=7)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=6)
    save_figure(fig, out.with_suffix(""), sources, formats=(out.suffix,), param="--out")


@dataclass(frozen=True)
class PlotRunsConfig:
    """What ``plot-runs`` draws, and where."""

    runs: tuple[str, ...]
    """The run folders (``RUN_DIR ...``)."""
    out: Path
    """The figure, .png or .pdf (``--out``)."""
    metric: str | None
    """The progress.csv column drawn (``--metric``; None: the environment's usual one)."""


def configure(args: argparse.Namespace) -> PlotRunsConfig:
    out = Path(args.out)
    require(out.suffix in FIGURE_FORMATS, "--out",
            "a file name ending in " + " or ".join(FIGURE_FORMATS), args.out)
    check_writable_dir(out.parent, "--out")
    require(args.metric is None or args.metric in METRICS, "--metric",
            "one of " + ", ".join(METRICS), args.metric)
    return PlotRunsConfig(runs=tuple(args.runs), out=out, metric=args.metric)


def run(cfg: PlotRunsConfig) -> int:
    runs = read_runs(list(cfg.runs))
    envs = sorted({str(c["env_name"]) for c, _ in runs})
    metric = cfg.metric or ("average_return" if envs == ["bus"] else
                            "average_discounted_return")
    missing = [name for name, (_, t) in zip(cfg.runs, runs) if metric not in t]
    require(not missing, "RUN_DIR", f"runs whose {PROGRESS} has a {metric} column",
            ", ".join(missing))
    labelled = groups(runs)
    out = cfg.out
    plot(labelled, metric, " and ".join(envs), out, [Path(r) / PROGRESS for r in cfg.runs])
    for label, tables in labelled:
        c = curve(tables, metric)
        print(f"{label}: {metric} {c['mean'].iloc[-1]:.4g} at epoch {int(c['epoch'].iloc[-1])}")
    print(f"wrote {out}")
    return 0
