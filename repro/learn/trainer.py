"""PS-TRPO with M-GAE: the training loop and the ``train`` command (SPEC section 4).

One epoch = sample ``batch_episodes`` whole episodes with the current shared policy, compute M-GAE
advantages with the current baseline, take one TRPO step, update the observation normaliser, then
fit the baseline to the batch's discounted returns (in the new normalisation, which it will be used
with). After every epoch a row is appended to the run folder's ``progress.csv`` and a checkpoint is
written atomically; running the same command again resumes from the checkpoint and ends with
exactly the parameters and progress table of an uninterrupted run.

Threads: torch and numpy's BLAS run on one thread (:func:`~repro.learn.policy.blas_on_one_thread`
says why). Memory: malloc keeps freed blocks (:func:`~repro.core.memory.keep_freed_memory` says
why).

Determinism: torch is seeded from the run seed; the policy's sampling draws come from one numpy
Generator owned by the trainer (its state is checkpointed); epoch e's environment seed is derived
from (seed, e). Timing columns are the only run-to-run differences in the outputs.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any, ClassVar

import numpy as np
import pandas as pd
import torch

from repro.core.config import SCALES, to_dict
from repro.core.errors import UsageError, require
from repro.core.io import (append_csv, atomic_path, check_writable_dir, provenance, sidecar_path,
                           write_csv, write_json, write_text)
from repro.core.memory import keep_freed_memory
from repro.core.progress import progress
from repro.core.rollout import BatchEnv
from repro.learn.baseline import BASELINES, make_baseline
from repro.learn.m_gae import m_gae_paths
from repro.learn.network import TanhMLP
from repro.learn.policy import (DTYPE, CategoricalPolicy, ObsNormalizer, Sampler,
                                blas_on_one_thread)
from repro.learn.trpo import normalize, trpo_step

ENVS = ("toy", "wildfire", "bus")
"""Environment packages ``repro.envs.<name>`` that ``--env`` accepts (imported lazily)."""

ENV_DEFAULTS: dict[str, dict[str, Any]] = {
    "toy": dict(lam=1.0, batch_episodes=50, epochs=40),
    "wildfire": dict(lam=1.0, batch_episodes=600, epochs=300),  # paper: 600-1200 eps, 300 epochs
    "bus": dict(lam=2.0, batch_episodes=540, epochs=300),  # paper: lambda 2.0, 540 episodes
}
"""Per-environment defaults (the paper's settings), applied under the scale and the command line."""

# Independent child streams of the run seed.
_TORCH_STREAM, _SAMPLER_STREAM, _ENV_STREAM, _FVP_STREAM = 0, 1, 2, 3


@dataclass(frozen=True)
class TrainConfig:
    """Hyperparameters of one PS-TRPO + M-GAE run."""

    env: str = "toy"
    """Environment package under repro.envs."""
    epochs: int = 40
    """Policy updates; each samples a fresh batch."""
    batch_episodes: int = 50
    """Whole episodes simulated per epoch (the paper counts batches in episodes)."""
    lam: float = 1.0
    """M-GAE lambda: advantages discount deltas by exp(-gamma lam dt) per macro-action."""
    max_kl: float = 0.01
    """TRPO max step: bound on the mean KL between consecutive policies."""
    hidden: tuple[int, ...] = (32, 32)
    """Hidden layer sizes of the policy MLP (tanh)."""
    baseline: str = "linear"
    """Value baseline: "linear" (rllab's linear feature baseline, as the released implementation)
    or "mlp" (see repro.learn.baseline)."""
    baseline_hidden: tuple[int, ...] = (32, 32)
    """Hidden layer sizes of the "mlp" baseline (tanh)."""
    baseline_iters: int = 20
    """Full-batch L-BFGS iterations fitting the "mlp" baseline each epoch."""
    cg_iters: int = 10
    """Conjugate-gradient iterations for the natural-gradient direction (rllab: 10)."""
    cg_damping: float = 1e-5
    """Multiple of the identity added to the Fisher matrix (rllab's reg_coeff)."""
    backtrack_ratio: float = 0.8
    """Line-search shrink factor (rllab: 0.8)."""
    max_backtracks: int = 15
    """Line-search tries before the step is rejected (rllab: 15)."""
    fvp_subsample: float = 0.2
    """Fraction of the batch's decisions (drawn without replacement, afresh each epoch) on which
    the Fisher-vector products are computed; 1 = all (exact). rllab's ``subsample_factor``; OpenAI
    Baselines' TRPO uses every 5th decision. The Fisher matrix of a few thousand decisions is as
    good as that of the whole batch, and the products are most of a TRPO step's cost: on 25,000
    decisions (the paper's wildfire batch) 0.2 cut a step from 0.26 s to 0.07 s on a 2-core machine,
    with the autograd products that came before repro.learn.network."""
    normalize_obs: bool = True
    """Running mean/std observation normalisation (frozen within a batch)."""
    seed: int = 0
    """Root of every random stream of the run."""

    SCALES: ClassVar[dict[str, dict[str, Any]]] = {
        "smoke": dict(epochs=2, batch_episodes=8),
        "quick": {},
        "paper": {},
    }

    def validate(self) -> None:
        require(self.env in ENVS, "--env", "one of " + ", ".join(ENVS), self.env)
        require(self.epochs >= 1, "--epochs", "an integer >= 1", self.epochs)
        require(self.batch_episodes >= 1, "--batch-episodes", "an integer >= 1",
                self.batch_episodes)
        require(self.lam >= 0 and math.isfinite(self.lam), "--lam", "a number >= 0", self.lam)
        require(self.max_kl > 0 and math.isfinite(self.max_kl), "--max-kl", "a number > 0",
                self.max_kl)
        require(len(self.hidden) >= 1 and min(self.hidden) >= 1, "--hidden",
                "one or more positive layer sizes", list(self.hidden))
        require(self.baseline in BASELINES, "--baseline", "one of " + ", ".join(BASELINES),
                self.baseline)
        require(self.baseline_iters >= 1, "baseline_iters", "an integer >= 1", self.baseline_iters)
        require(self.cg_iters >= 1, "cg_iters", "an integer >= 1", self.cg_iters)
        require(self.cg_damping >= 0, "cg_damping", ">= 0", self.cg_damping)
        require(0 < self.backtrack_ratio < 1, "backtrack_ratio", "in (0, 1)", self.backtrack_ratio)
        require(0 < self.fvp_subsample <= 1, "--fvp-subsample", "in (0, 1]", self.fvp_subsample)
        require(self.max_backtracks >= 1, "max_backtracks", "an integer >= 1", self.max_backtracks)


def train_config(scale: str, env: str, **overrides: Any) -> TrainConfig:
    """The config at ``scale`` for ``env``: env defaults, then the scale, then explicit overrides
    (``None`` means not given)."""
    require(scale in SCALES, "--scale", "one of " + ", ".join(SCALES), scale)
    require(env in ENVS, "--env", "one of " + ", ".join(ENVS), env)
    fields = {**ENV_DEFAULTS[env], **TrainConfig.SCALES[scale], "env": env}
    fields.update({k: v for k, v in overrides.items() if v is not None})
    cfg = TrainConfig(**fields)
    cfg.validate()
    return cfg


def env_package(name: str) -> ModuleType:
    """``repro.envs.<name>``, imported only when asked for, so training works with whichever
    environment packages exist."""
    require(name in ENVS, "--env", "one of " + ", ".join(ENVS), name)
    try:
        return importlib.import_module(f"repro.envs.{name}")
    except ModuleNotFoundError as err:
        if err.name not in (f"repro.envs.{name}", "repro.envs"):
            raise
        raise UsageError("--env", "an installed environment package", name) from None


def _stream(seed: int, *key: int) -> np.random.SeedSequence:
    return np.random.SeedSequence(seed, spawn_key=key)


def epoch_seed(seed: int, epoch: int) -> np.random.SeedSequence:
    """The environment seed of ``epoch`` (0-based) of a run with root ``seed``."""
    return _stream(seed, _ENV_STREAM, epoch)


class Trainer:
    """Owns the policy, baseline, normaliser and sampling generator of one run."""

    def __init__(self, cfg: TrainConfig, env: BatchEnv, out: str | Path | None = None,
                 env_config: Any = None):
        cfg.validate()
        require(env.gamma > 0 and math.isfinite(env.gamma), "--gamma", "a number > 0", env.gamma)
        self.cfg, self.env = cfg, env
        self.out = None if out is None else Path(out)
        self.env_config = env_config
        self.run_config = run_config(cfg, env_config, env.name)
        torch.set_num_threads(1)
        keep_freed_memory()
        torch.manual_seed(int(_stream(cfg.seed, _TORCH_STREAM).generate_state(1)[0]))
        self.policy = CategoricalPolicy(env.obs_dim, env.n_actions, cfg.hidden)
        self.baseline = make_baseline(cfg.baseline, env.obs_dim, cfg.baseline_hidden,
                                      cfg.baseline_iters)
        self.normalizer = ObsNormalizer(env.obs_dim)
        self.rng = np.random.default_rng(_stream(cfg.seed, _SAMPLER_STREAM))
        self.epoch = 0
        self.rows: list[dict[str, Any]] = []

    # --- one epoch -------------------------------------------------------------------------------

    def run_epoch(self) -> dict[str, Any]:
        cfg, env = self.cfg, self.env
        t0 = time.perf_counter()
        ro = env.rollout(Sampler(self.policy, self.normalizer, self.rng), cfg.batch_episodes,
                         epoch_seed(cfg.seed, self.epoch))
        t1 = time.perf_counter()
        z = self.normalizer(ro.obs)
        index = ro.step_index()
        values = self.baseline.predict(z, index)
        adv, ret = m_gae_paths(ro.rewards, ro.durations, values, ro.path_start, env.gamma, cfg.lam)
        explained = 1.0 - np.var(ret - values) / np.var(ret) if np.var(ret) > 0 else 0.0
        stats = trpo_step(TanhMLP(self.policy.net), torch.as_tensor(z, dtype=DTYPE),
                          torch.as_tensor(ro.actions), torch.as_tensor(normalize(adv), dtype=DTYPE),
                          max_kl=cfg.max_kl, cg_iters=cfg.cg_iters, cg_damping=cfg.cg_damping,
                          backtrack_ratio=cfg.backtrack_ratio, max_backtracks=cfg.max_backtracks,
                          fvp_rows=self.fvp_rows(ro.n_decisions))
        t2 = time.perf_counter()
        # the normaliser moves on first, so that the baseline is fitted in the coordinates in which
        # it will predict the next batch's values
        if cfg.normalize_obs:
            self.normalizer.update(ro.obs)
        baseline_loss = self.baseline.fit(self.normalizer(ro.obs), index, ret)
        t3 = time.perf_counter()
        row = dict(
            epoch=self.epoch,
            average_return=float(ro.episode_return.mean()),
            average_discounted_return=float(ro.discounted_path_returns(env.gamma).mean()),
            kl=stats.kl, entropy=stats.entropy, surrogate_before=stats.surrogate_before,
            surrogate_after=stats.surrogate_after, backtracks=stats.backtracks,
            accepted=int(stats.accepted), explained_variance=float(explained),
            baseline_loss=baseline_loss, batch_episodes=cfg.batch_episodes,
            decisions=ro.n_decisions,
            seconds_sim=t1 - t0, seconds_trpo=t2 - t1, seconds_baseline=t3 - t2,
            seconds_update=t3 - t1,
        )
        self.epoch += 1
        return row

    def fvp_rows(self, n_decisions: int) -> torch.Tensor | None:
        """The decisions of this epoch's batch on which TRPO computes Fisher-vector products:
        ``fvp_subsample`` of them, drawn afresh each epoch (None: all)."""
        cfg = self.cfg
        if cfg.fvp_subsample == 1:
            return None
        rng = np.random.default_rng(_stream(cfg.seed, _FVP_STREAM, self.epoch))
        n_rows = max(1, int(cfg.fvp_subsample * n_decisions))
        return torch.as_tensor(np.sort(rng.choice(n_decisions, n_rows, replace=False)))

    def train(self) -> pd.DataFrame:
        """Run (or resume) up to ``cfg.epochs`` epochs; returns the progress table. A run folder
        also gets ``progress.provenance.json``: what this call ran, from which commit, on what."""
        t_start, first_epoch = time.perf_counter(), self.epoch
        if self.out is not None:
            self._start_or_resume()
            first_epoch = self.epoch
        with blas_on_one_thread():
            for _ in progress(range(self.epoch, self.cfg.epochs), f"train {self.cfg.env}",
                              total=self.cfg.epochs - self.epoch):
                t0 = time.perf_counter()
                row = self.run_epoch()
                row["seconds"] = time.perf_counter() - t0
                self.rows.append(row)
                if self.out is not None:
                    # the row goes first, so progress.csv never holds fewer rows than the checkpoint
                    # has epochs; appended, because rewriting the table every epoch grows with the
                    # run (0.18 s per epoch by epoch 1,550 of a paper-scale C6 run)
                    append_csv(self.out / PROGRESS, pd.DataFrame([row], columns=PROGRESS_COLUMNS))
                    self.save_checkpoint(self.out / CHECKPOINT)
        if self.out is not None:
            write_json(sidecar_path(self.out / PROGRESS), provenance(
                self.run_config, command="train", scale=None, seed=self.cfg.seed,
                wall_seconds=time.perf_counter() - t_start,
                extra={"epochs_before": first_epoch, "epochs_after": self.epoch}))
        return self.progress()

    def progress(self) -> pd.DataFrame:
        return pd.DataFrame(self.rows, columns=PROGRESS_COLUMNS)

    # --- checkpoints -----------------------------------------------------------------------------

    def state_dict(self) -> dict[str, Any]:
        return {
            "epoch": self.epoch,
            "policy": self.policy.state_dict(),
            "baseline": self.baseline.state_dict(),
            "normalizer": self.normalizer.state_dict(),
            "sampler_rng": self.rng.bit_generator.state,
            "torch_rng": torch.get_rng_state(),
            "run_config": self.run_config,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.epoch = int(state["epoch"])
        self.policy.load_state_dict(state["policy"])
        self.baseline.load_state_dict(state["baseline"])
        self.normalizer.load_state_dict(state["normalizer"])
        self.rng.bit_generator.state = state["sampler_rng"]
        torch.set_rng_state(state["torch_rng"])

    def save_checkpoint(self, path: Path) -> None:
        with atomic_path(path) as tmp:
            torch.save(self.state_dict(), tmp)

    def _start_or_resume(self) -> None:
        """Write config.json, or check it against the run already in ``out`` and load its
        checkpoint. Only ``epochs`` may differ (to extend or finish a run)."""
        assert self.out is not None
        if not holds_same_run(self.out, self.cfg, self.env_config, self.env.name):
            raise UsageError("--out", "empty or holding a run with the same settings",
                             str(self.out))
        state = None
        if (self.out / CHECKPOINT).exists():
            state = load_checkpoint(self.out / CHECKPOINT)
            _check_rows(self.out / PROGRESS, int(state["epoch"]), state.get("rows"))
        write_json(self.out / "config.json", self.run_config)
        if state is not None:
            self.load_state_dict(state)
            self.rows = _completed_rows(self.out / PROGRESS, self.epoch, state.get("rows"))


def _check_rows(path: Path, epochs: int, saved_rows: list | None) -> None:
    """Refuse to resume a run whose progress.csv lacks rows of the checkpointed epochs (deleted or
    replaced by hand): they cannot be rebuilt without running those epochs again."""
    rows = len(saved_rows) if saved_rows is not None else (
        len(path.read_text().splitlines()) - 1 if path.exists() else 0)
    require(rows >= epochs, "--out", f"a run folder whose {PROGRESS} holds the {epochs} epochs of "
            f"its {CHECKPOINT} (it holds {max(rows, 0)}; delete {CHECKPOINT} to start again)",
            str(path.parent))


def _completed_rows(path: Path, epochs: int, saved_rows: list | None) -> list[dict[str, Any]]:
    """The progress rows of a resumed run's ``epochs`` checkpointed epochs; progress.csv is cut
    back to them (a run stopped between appending a row and checkpointing leaves one more, perhaps
    cut short). Checkpoints from before progress.csv was appended to carry the rows themselves."""
    if saved_rows is not None:
        write_csv(path, pd.DataFrame(saved_rows[:epochs], columns=PROGRESS_COLUMNS))
    lines = path.read_text().splitlines(keepends=True)
    if len(lines) != epochs + 1:
        write_text(path, "".join(lines[:epochs + 1]))
    return pd.read_csv(path).to_dict("records")


CHECKPOINT = "checkpoint.pt"
PROGRESS = "progress.csv"
PROGRESS_COLUMNS = [
    "epoch", "average_return", "average_discounted_return", "kl", "entropy", "surrogate_before",
    "surrogate_after", "backtracks", "accepted", "explained_variance", "baseline_loss",
    "batch_episodes", "decisions", "seconds_sim", "seconds_trpo", "seconds_baseline",
    "seconds_update", "seconds",
]
"""The columns of progress.csv, one row per epoch. Timing (wall seconds): ``seconds_sim`` the
rollout; ``seconds_trpo`` everything from the batch to the TRPO step's end (standardisation,
baseline prediction, M-GAE, the step); ``seconds_baseline`` the normaliser's update, the
standardisation in its new moments and the baseline's fit; ``seconds_update`` the last two
together; ``seconds`` the epoch (without writing its row and checkpoint). ``bench-learn`` times
the pieces one by one."""
TIMING_COLUMNS = [c for c in PROGRESS_COLUMNS if c.startswith("seconds")]


def load_checkpoint(path: str | Path) -> dict[str, Any]:
    # weights_only=False: the file holds numpy RNG state and plain rows, and is written by this code
    return torch.load(path, weights_only=False)


def load_trained_run(path: str | Path, env_name: str,
                     param: str = "--checkpoint") -> dict[str, Any]:
    """The checkpoint at ``path`` of a training run on ``env_name``; a UsageError naming ``param``
    if it is none (missing, not a checkpoint, or a run on another environment)."""
    allowed = f"the {CHECKPOINT} of a {env_name} training run"
    require(Path(path).is_file(), param, allowed, str(path))
    try:
        state = load_checkpoint(path)
    except Exception:  # not a torch file: reported as bad input, not as a crash
        raise UsageError(param, allowed, str(path)) from None
    require(isinstance(state, dict) and state.get("run_config", {}).get("env_name") == env_name,
            param, allowed, str(path))
    return state


def epochs_done(out: str | Path) -> int:
    """Epochs of the run in folder ``out`` that its checkpoint holds (0 if it has none)."""
    path = Path(out) / CHECKPOINT
    return int(load_checkpoint(path)["epoch"]) if path.exists() else 0


def policy_from_checkpoint(path: str | Path, rng: np.random.Generator) -> Sampler:
    """The trained policy of a run folder's checkpoint, ready to hand to an engine."""
    return policy_from_state(load_checkpoint(path), rng)


def policy_from_state(state: dict[str, Any], rng: np.random.Generator) -> Sampler:
    """The trained policy of a loaded checkpoint (:func:`load_checkpoint`)."""
    cfg = state["run_config"]["train"]
    obs_dim = len(state["normalizer"]["mean"])
    n_actions = state["policy"][next(reversed(state["policy"]))].shape[0]
    policy = CategoricalPolicy(obs_dim, n_actions, cfg["hidden"])
    policy.load_state_dict(state["policy"])
    normalizer = ObsNormalizer(obs_dim)
    normalizer.load_state_dict(state["normalizer"])
    return Sampler(policy, normalizer, rng)


def config_dict(cfg: Any) -> Any:
    """A dataclass config as a dict (other configs unchanged), for config.json and sidecars."""
    return to_dict(cfg) if dataclasses.is_dataclass(cfg) else cfg


def saved_defaults(config_type: type) -> dict[str, Any]:
    """What a run recorded before a setting existed held for it: its default, unless the config
    class names another value in ``BEFORE_ADDED`` (e.g. a switch whose default changed when it
    was added)."""
    return {**to_dict(config_type()), **getattr(config_type, "BEFORE_ADDED", {})}


def run_config(cfg: TrainConfig, env_config: Any, env_name: str) -> dict[str, Any]:
    """What a run folder's config.json holds: the settings that determine the run."""
    return {"train": to_dict(cfg), "env": config_dict(env_config), "env_name": env_name}


def holds_same_run(out: Path, cfg: TrainConfig, env_config: Any, env_name: str) -> bool:
    """Whether the run folder ``out`` is new (missing or empty) or holds a run with these settings;
    only ``epochs`` may differ, to extend or finish a run."""
    path = Path(out) / "config.json"
    if not path.exists():  # a folder of other files is not a run to mix this one into
        return not Path(out).is_dir() or not any(Path(out).iterdir())
    saved = json.loads(path.read_text())
    # settings added to the code since the run started held their defaults then (or the values
    # a config names as those they had before they were added)
    defaults = {"train": to_dict(TrainConfig()),
                "env": saved_defaults(type(env_config)) if dataclasses.is_dataclass(env_config)
                else None}
    for part, default in defaults.items():
        if default is not None and isinstance(saved.get(part), dict):
            saved[part] = {**_as_json(default), **saved[part]}
    mine = _as_json(run_config(cfg, env_config, env_name))
    return _without_epochs(saved) == _without_epochs(mine)


def _as_json(value: Any) -> Any:
    return json.loads(json.dumps(value, default=str))


def _without_epochs(run_config: dict) -> dict:
    return {**run_config, "train": {k: v for k, v in run_config["train"].items() if k != "epochs"}}


# --- command line --------------------------------------------------------------------------------

def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--env", required=True, help="environment: " + ", ".join(ENVS))
    p.add_argument("--scale", default="quick", help="one of " + ", ".join(SCALES))
    p.add_argument("--seed", type=int, default=0, help="root seed of every random stream")
    p.add_argument("--out", help="run folder (default runs/<env>/seed<seed>); rerun to resume")
    p.add_argument("--epochs", type=int, help="policy updates")
    p.add_argument("--batch-episodes", type=int, help="episodes per epoch")
    p.add_argument("--lam", type=float, help="M-GAE lambda (wildfire 1.0, bus 2.0)")
    p.add_argument("--max-kl", type=float, help="TRPO max step (0.01)")
    p.add_argument("--hidden", type=int, nargs="+", help="policy hidden sizes (32 32)")
    p.add_argument("--baseline", help="value baseline: " + ", ".join(BASELINES) + " (linear)")
    p.add_argument("--fvp-subsample", type=float,
                   help="fraction of decisions for Fisher-vector products (1 = all)")
    p.add_argument("--no-obs-norm", action="store_true",
                   help="switch off observation normalisation")


def extend_arguments(p: argparse.ArgumentParser, argv: list[str]) -> None:
    """Add the chosen environment's own options (``--env`` decides which)."""
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--env")
    name = pre.parse_known_args(argv)[0].env
    if name is not None:
        env_package(name).add_env_arguments(p)


def make_from_args(args: argparse.Namespace, **overrides: Any) -> tuple[TrainConfig, BatchEnv, Any]:
    """Train config, environment and environment config from parsed ``train``-style options."""
    pkg = env_package(args.env)
    cfg = train_config(args.scale, args.env, seed=args.seed, epochs=args.epochs,
                       batch_episodes=args.batch_episodes, lam=args.lam, max_kl=args.max_kl,
                       hidden=tuple(args.hidden) if args.hidden else None, baseline=args.baseline,
                       fvp_subsample=args.fvp_subsample,
                       normalize_obs=False if args.no_obs_norm else None, **overrides)
    env_cfg = pkg.config_from_args(args)
    return cfg, pkg.make_env(env_cfg), env_cfg


def run(args: argparse.Namespace) -> int:
    cfg, env, env_cfg = make_from_args(args)
    out = check_writable_dir(args.out or f"runs/{cfg.env}/seed{cfg.seed}", "--out")
    frame = Trainer(cfg, env, out, env_cfg).train()
    last = frame.iloc[-1]
    extra = (f" (the run already had more than --epochs {cfg.epochs}: nothing trained)"
             if len(frame) > cfg.epochs else "")
    print(f"{cfg.env}: {len(frame)} epochs{extra}, average return {last.average_return:.6g}, "
          f"average discounted return {last.average_discounted_return:.6g} -> {out}")
    return 0
