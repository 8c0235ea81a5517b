"""The bus policies the drivers name (No Holding, the authors' and our thresholds, a trained MLP,
a trained GRU sampled or greedy), made from the result files and run folders where they come
from."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd

from repro.core.errors import UsageError, require
from repro.core.rollout import DecisionBatch, Policy
from repro.envs.bus import make_env
from repro.envs.bus.metrics import arrival_table
from repro.envs.bus.params import SWITCHES, BusConfig
from repro.envs.bus.policies import (AUTHORS_THRESHOLDS, ThresholdPolicy, check_thresholds,
                                     no_holding)
from repro.learn.config import DEFAULT_LEARNER, LEARNERS, learner_stem
from repro.learn.trained_policy import (check_fits, load_trained_run, policy_from_state,
                                        trained_env_config)
from repro.runs.results import read_result
from repro.runs.run_folder import CHECKPOINT
from repro.studies.kit.options import Folders
from repro.studies.kit.sweep import policy_stream


BUS_VARIANTS = ("corrected", *SWITCHES)
"""The options that choose the corridor's semantics (``--corrected``, B1-B5), and so the folder
of the results (:func:`semantics_folder`): a bus driver's variants, not departures from its
scale's settings (:func:`repro.studies.kit.options.scale_departures`)."""


def semantics_folder(results: Path, bus: BusConfig) -> Path:
    """Where the bus results of ``bus``'s semantics lie under the results folder ``results``:
    itself for the released simulator's (B1-B5 on), else its subfolder named for them
    (``corrected``, or the switches on, e.g. ``b1-b4``). The bus writes the same file names for
    every semantics; the subfolder keeps one semantics' results from replacing another's."""
    return results if bus.semantics == "released" else results / bus.semantics


def semantics_folders(folders: Folders, bus: BusConfig) -> Folders:
    """A bus driver's ``folders`` with its results and figures in :func:`semantics_folder`."""
    return folders if bus.semantics == "released" else folders.within(bus.semantics)


class TrainedPolicy:
    """A trained policy (MLP or GRU) acting greedily, the most probable action (ties: the
    lowest), or, given ``rng``, sampling its actions from that generator.

    The figures show one episode per policy; acting greedily makes that episode the trained
    policy's exact behaviour, as it is for the deterministic baselines; the paper's GRU panel was
    drawn with sampled actions. The run must have been trained with the switches B1-B5 of ``cfg``
    (they change what it observes). ``param``: the option that named the run, which a refusal
    names.
    """

    def __init__(self, run: str | Path, cfg: BusConfig, param: str = "--mlp-run",
                 rng: np.random.Generator | None = None):
        state = load_trained_run(Path(run) / CHECKPOINT, "bus", param)
        trained = trained_env_config(state, BusConfig, param)
        check_fits(state, make_env(trained), param, run)
        differ = [f for f in SWITCHES if getattr(trained, f) != getattr(cfg, f)]
        require(not differ, param, "a run trained with this command's switches B1-B5 "
                f"(it differs in {', '.join(differ)})", str(run))
        self.sampled = rng is not None
        # without rng the generator is never drawn from: greedy actions need no randomness
        self.sampler = policy_from_state(state, rng or np.random.default_rng(0))

    def __call__(self, batch: DecisionBatch) -> np.ndarray:
        return self.sampler(batch) if self.sampled else self.sampler.greedy(batch)


POLICIES = ("nohold", "authors", "thresholds", "mlp", "gru", "gru-greedy")
"""Policy names the bus drivers accept, in panel order: No Holding, the authors' thresholds, ours
(``make bus-thresholds``), the trained MLP (greedy), the trained GRU sampled and greedy."""
DEFAULT_PANELS = POLICIES[:4]
"""The panels of a bus picture without ``--policies``."""
GRU_PANELS = ("gru", "gru-greedy")
PICTURE_STREAM = 7
"""The child stream, of the trained run's name (:func:`repro.studies.kit.sweep.policy_stream`,
root 0), that a sampled picture's actions draw from."""

THRESHOLDS_CSV = "bus_thresholds.csv"


def lambda_summary_csv(learner: str | None = None) -> str:
    """The lambda sweep's summary of ``learner`` (None: the default learner's)."""
    return f"{learner_stem('bus_lambda', learner or DEFAULT_LEARNER)}_summary.csv"


def read_thresholds(results_dir: str | Path, param: str = "--thresholds") -> np.ndarray:
    """Our T1, T2, T3 (s) from results/bus_thresholds.csv, written by `make bus-thresholds`;
    without it (or with a CSV its sidecar does not describe), a UsageError naming ``param``, the
    option that could have supplied them."""
    path = Path(results_dir) / THRESHOLDS_CSV
    try:
        table = read_result(path)
    except FileNotFoundError:
        if param == "--thresholds":
            raise UsageError(param, f"given, or {path} written first by `make bus-thresholds`"
                             ) from None
        raise UsageError(param, f"a folder holding {THRESHOLDS_CSV} (`make bus-thresholds` "
                         "writes it)", str(results_dir)) from None
    except ValueError:
        table = None
    try:
        row = table.query("source == 'ours'").iloc[0]
        return check_thresholds(np.array([row.T1, row.T2, row.T3], float))[0]
    except (ValueError, KeyError, IndexError, AttributeError, pd.errors.UndefinedVariableError):
        raise UsageError(param, f"a folder whose {THRESHOLDS_CSV} is the table "
                         "`make bus-thresholds` writes (run it again)",
                         str(results_dir)) from None


def best_run(results_dir: str | Path, param: str = "--mlp-run",
             learner: str | None = None) -> Path:
    """The run folder of ``learner``'s lambda sweep's best run (highest final return), from
    results/bus_lambda[_suite]_summary.csv, written by `make fig-bus-lambda`; a UsageError naming
    ``param`` without it."""
    require(learner is None or learner in LEARNERS, "--learner", "one of " + ", ".join(LEARNERS),
            learner)
    path = Path(results_dir) / lambda_summary_csv(learner)
    try:
        runs = read_result(path).query("policy == 'mlp-run'")
        return Path(runs.run.iloc[int(np.argmax(runs.final_iqm.to_numpy(float)))])
    except FileNotFoundError:
        raise UsageError(param, f"given, or {path} written first by `make fig-bus-lambda`"
                         ) from None
    except (ValueError, KeyError, IndexError, AttributeError, TypeError,
            pd.errors.UndefinedVariableError):
        raise UsageError(param, f"given, or a {path.name} as `make fig-bus-lambda` "
                         "writes it (run it again)", str(path)) from None


def make_policy(name: str, cfg: BusConfig, *, thresholds: np.ndarray | None = None,
                results_dir: str | Path = "results/paper",
                mlp_run: str | Path | None = None, results_param: str | None = None,
                mlp_param: str = "--mlp-run", learner: str | None = None,
                gru_run: str | Path | None = None, gru_param: str = "--gru-run") -> Policy:
    """The policy called ``name`` on corridor ``cfg``; our thresholds default to the optimised
    ones in ``results_dir``, the trained MLP to the best run of ``learner``'s lambda sweep
    recorded there; the GRU is the run ``gru_run`` (sampled: from the stream of its name).
    Refusals name the options the caller has: ``mlp_param`` and ``gru_param`` for the runs,
    ``results_param`` (if given) for the results folder, else --thresholds and --mlp-run."""
    require(name in POLICIES, "--policy", "one of " + ", ".join(POLICIES), name)
    if name in GRU_PANELS:
        require(gru_run is not None, gru_param, f"given with --policy {name}", gru_run)
        rng = (np.random.default_rng(policy_stream(0, PICTURE_STREAM, Path(gru_run).name))
               if name == "gru" else None)
        return TrainedPolicy(gru_run, cfg, gru_param, rng)
    if name == "nohold":
        return no_holding
    if name == "mlp":
        run = (best_run(results_dir, results_param or mlp_param, learner) if mlp_run is None
               else mlp_run)
        return TrainedPolicy(run, cfg, mlp_param)
    if name == "authors":
        thresholds = np.array(AUTHORS_THRESHOLDS)
    elif thresholds is None:
        thresholds = read_thresholds(results_dir, results_param or "--thresholds")
    return ThresholdPolicy(thresholds, headway_in_minutes=not cfg.b2_headway)


PICTURE_HORIZON = 6 * 3600.0
"""The episode length of the paper's bus pictures (s): the released code's PLOTTING runs."""


@dataclasses.dataclass(frozen=True)
class PolicySources:
    """Where the bus policies a command draws or evaluates come from, as its options give them
    (None: the default source)."""

    thresholds: tuple[float, ...] | None = None
    """Our thresholds T1-T3 in seconds (``--thresholds``; default: the optimised ones in the
    results folder)."""
    mlp_run: str | None = None
    """The trained MLP's run folder (``--mlp-run``; default: the lambda sweep's best run)."""
    gru_run: str | None = None
    """The trained GRU's run folder (``--gru-run``)."""
    learner: str | None = None
    """The learner whose lambda sweep's best run is the MLP (``--learner``; default authors)."""

    @classmethod
    def of(cls, args: argparse.Namespace) -> PolicySources:
        """The sources a command's options name (thresholds checked)."""
        thresholds = None if args.thresholds is None else tuple(args.thresholds)
        if thresholds is not None:
            check_thresholds(thresholds)
        return cls(thresholds=thresholds, mlp_run=args.mlp_run,
                   gru_run=getattr(args, "gru_run", None), learner=args.learner)

    def policy(self, name: str, cfg: BusConfig, results_dir: Path) -> Policy:
        """The policy called ``name`` on corridor ``cfg``, from these sources, else the optimised
        thresholds and the best trained run recorded in ``results_dir``."""
        thresholds = None if self.thresholds is None else np.array(self.thresholds, float)
        return make_policy(name, cfg, thresholds=thresholds, results_dir=results_dir,
                           mlp_run=self.mlp_run, learner=self.learner, gru_run=self.gru_run)


def picture_arrivals(policy: Policy, cfg: BusConfig, n_episodes: int = 1) -> pd.DataFrame:
    """The arrival table of ``n_episodes`` episodes of the paper's pictures (6 h)."""
    pic = dataclasses.replace(cfg, horizon=PICTURE_HORIZON)
    return arrival_table(make_env(pic).rollout(policy, n_episodes), cfg.n_stops)
