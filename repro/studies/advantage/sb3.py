"""``beyond-sb3``, beyond the paper: does M-GAE close Stable-Baselines3's gap? (docs/own-learner.md)

At one budget, ``updates`` updates of ``batch_decisions`` decisions each, and ``seeds`` seeds per
method, on the wildfire (ED, the released simulator) and the bus (its paper lambda, 2):

- ``sb3-ppo-gae``: SB3's PPO through the PettingZoo ParallelEnv (:mod:`repro.learn.sb3`) with
  SB3's own GAE, one step per decision: gamma_d = exp(-gamma m), lambda_d = exp(-gamma (lam - 1)
  m), m the first batch's mean macro-action duration (what a user of the library would do);
- ``sb3-ppo-mgae``: the same PPO with :class:`~repro.learn.sb3.MGAERolloutBuffer`, M-GAE;
- ``ps-trpo-mgae``: this suite's PS-TRPO with M-GAE, the authors' learner (the released runner's
  settings), trained by the sweep machinery (checkpointed each epoch);
- the heuristic beside them: nearest-fire on the wildfire, no holding on the bus.

Every policy is scored on the same test episodes of its environment (the policy sampling, as the
suite's evaluation): ADR, the average discounted return over agents' paths. The SB3 runs are
each one task (joblib workers, or ``--scheduler``), a round of ``--n-jobs`` at a time; a finished
run's result and model are kept in its folder under ``--runs-dir``/beyond-sb3 as its round ends,
so the same command resumes with the runs not yet done (an interrupted SB3 run starts again from
its beginning: it takes about 20 CPU seconds at paper scale).

Outputs: ``results/beyond_sb3.csv`` (one row per run), ``beyond_sb3_summary.csv`` (per environment
and method: mean, SEM, IQM, 95% bootstrap CI of the mean; for M-GAE the share of the gap between
SB3's GAE and PS-TRPO that it closes, with a bootstrap CI), ``figures/beyond_sb3.png/.pdf``.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import io
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pandas as pd

from repro.core.config import Validated, for_scale, from_recorded, given_fields
from repro.core.errors import UsageError
from repro.core.rollout import children
from repro.envs import env_package, train_defaults
from repro.learn.config import train_config
from repro.runs.files import write_bytes, write_json
from repro.runs.provenance import provenance
from repro.runs.results import read_provenance, save_figure, write_result
from repro.runs.stats import bootstrap_ci, ci_side, iqm, sem
from repro.studies.kit.options import Command, Folders, add_replot, read_for_replot, replot_figures
from repro.studies.kit.sweep import (TrainJob, add_study_arguments, map_tasks, run_sweep,
                                    run_sweeps)
from repro.studies.wildfire.study import adr, evaluate

ENVS = ("wildfire", "bus")
METHODS = {
    "sb3-ppo-gae": "SB3 PPO, its own GAE per decision",
    "sb3-ppo-mgae": "SB3 PPO, M-GAE buffer",
    "ps-trpo-mgae": "PS-TRPO, M-GAE (authors' learner)",
}
"""The trained methods, by name, with their label."""
HEURISTICS = {"wildfire": "nearest", "bus": "no-holding"}
"""The heuristic tested beside the trained policies, per environment."""
COLUMNS = ("env", "method", "lam", "seed", "updates", "batch_decisions", "train_adr_last",
           "gamma_d", "seconds", "seconds_collect", "seconds_advantages", "seconds_train", "score",
           "score_sem", "episode_return", "run")
"""The columns of beyond_sb3.csv, in order (``seconds*``: CPU seconds of training; the SB3 runs'
parts as :func:`repro.learn.sb3.train_update` times them)."""
RESULT = "result.json"
MODEL = "model.zip"
# Independent child streams of the root seed.
_TEST_ENV_STREAM, _TEST_POLICY_STREAM, _BOOT_STREAM = 0, 1, 2
# child streams of a run's seed for the SB3 updates
_SB3_STREAM = 7


@dataclass(frozen=True)
class Sb3StudyConfig(Validated):
    """The budget every trained method gets, and PPO's own settings."""

    updates: int = 20
    """Policy updates per run (PS-TRPO's epochs)."""
    batch_decisions: int = 5000
    """Decisions per update: PPO's ``n_steps`` (its rollout buffer), PS-TRPO's batch."""
    envs: int = 8
    """ParallelEnvs SB3's collection plays side by side (one policy call for all their deciding
    agents; :func:`repro.learn.sb3.collect_paths`)."""
    seeds: int = 5
    """Runs per method and environment (seeds seed .. seed + seeds - 1)."""
    minibatch: int = 250
    """PPO's minibatch size."""
    ppo_epochs: int = 5
    """PPO's passes over each batch."""
    hidden: int = 32
    """Units of the one hidden layer of PPO's policy and value networks (PS-TRPO's policy: the
    same)."""
    test_episodes: int = 1000
    """Test episodes per policy (the same episodes for every policy of an environment)."""
    n_boot: int = 2000
    """Bootstrap replicates of each CI."""

    SCALES: ClassVar[dict] = {
        "smoke": dict(updates=2, batch_decisions=300, envs=2, seeds=2, minibatch=100,
                      test_episodes=20, n_boot=200),
        "quick": dict(updates=5, seeds=3, test_episodes=200),
        "paper": {},
    }

    def validate(self) -> None:
        for name in ("updates", "batch_decisions", "envs", "seeds", "minibatch", "ppo_epochs",
                     "hidden",
                     "test_episodes", "n_boot"):
            self.check(getattr(self, name) >= 1, name, "an integer >= 1")
        self.check(self.minibatch <= self.batch_decisions, "minibatch",
                   "at most batch_decisions")


def env_config(env: str) -> Any:
    """The environment's default config: the wildfire's ED released simulator, the bus's."""
    package = env_package(env)
    return package.BusConfig() if env == "bus" else package.WildfireConfig()


def lam_of(env: str) -> float:
    """The paper's lambda of ``env`` (wildfire 1, bus 2)."""
    return float(train_defaults(env_package(env))["lam"])


def test_env_seed(seed: int, env: str) -> int:
    """The environment seed of ``env``'s test episodes (the same for every policy)."""
    return int(np.random.SeedSequence(seed, spawn_key=(_TEST_ENV_STREAM, ENVS.index(env)))
               .generate_state(1)[0])


def policy_stream(seed: int, env: str, method: str, run_seed: int) -> np.random.SeedSequence:
    """The stream a policy samples its test actions from: one per environment, method and run."""
    names = (*METHODS, "heuristic")
    return np.random.SeedSequence(seed, spawn_key=(_TEST_POLICY_STREAM, ENVS.index(env),
                                                   names.index(method), run_seed + 1))


def test_score(env: str, policy: Any, cfg: Sb3StudyConfig, env_seed: int) -> dict[str, float]:
    """ADR (and its SEM over paths) and the mean undiscounted episode return of ``policy`` on
    ``env``'s test episodes."""
    sim = env_package(env).make_env(env_config(env))
    rollout = evaluate(sim, policy, cfg.test_episodes, env_seed, keep_obs=False)
    mean, err = adr(rollout, sim.gamma)
    return dict(score=mean, score_sem=err, episode_return=float(rollout.episode_return.mean()))


def sb3_settings(cfg: Sb3StudyConfig, env: str, method: str, seed: int) -> dict[str, Any]:
    """What an SB3 run's folder records, and must match to be reused."""
    return dict(env=env, method=method, seed=seed, lam=lam_of(env),
                **{k: v for k, v in dataclasses.asdict(cfg).items()
                   if k not in ("seeds", "test_episodes", "n_boot")})


def sb3_run(env: str, method: str, seed: int, cfg: Sb3StudyConfig
            ) -> tuple[dict[str, Any], bytes]:
    """Train one SB3 PPO run; its row (without the test) and its model's bytes."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.utils import set_random_seed

    from repro.learn.sb3 import MGAERolloutBuffer, Spaces, path_adr, train_update

    torch.set_num_threads(1)
    env_cfg, lam = env_config(env), lam_of(env)
    make = importlib.import_module(f"repro.envs.{env}.pettingzoo_env").parallel_env
    parallel = [make(env_cfg) for _ in range(cfg.envs)]
    buffer = (dict(rollout_buffer_class=MGAERolloutBuffer,
                   rollout_buffer_kwargs=dict(gamma_rate=env_cfg.gamma, lam=lam))
              if method == "sb3-ppo-mgae" else {})
    model = PPO("MlpPolicy", Spaces(parallel[0]), n_steps=cfg.batch_decisions,
                batch_size=cfg.minibatch, n_epochs=cfg.ppo_epochs,
                policy_kwargs={"net_arch": [cfg.hidden]}, seed=seed, device="cpu", **buffer)
    model.set_logger(configure(None, []))
    history, seconds = [], {"collect": 0.0, "advantages": 0.0, "train": 0.0}

    def decision_discount(paths):  # SB3's one discount per decision, from the mean duration
        m = float(np.mean(np.concatenate([p["dur"] for p in paths])))
        model.gamma = model.rollout_buffer.gamma = float(np.exp(-env_cfg.gamma * m))
        model.rollout_buffer.gae_lambda = float(np.exp(-env_cfg.gamma * (lam - 1.0) * m))

    for u, stream in enumerate(children(np.random.SeedSequence(seed, spawn_key=(_SB3_STREAM,)),
                                        cfg.updates)):
        env_seed, torch_seed = (int(x) for x in stream.generate_state(2))
        set_random_seed(torch_seed)  # SB3 draws actions and minibatches from the global RNGs
        hook = decision_discount if (u == 0 and method == "sb3-ppo-gae") else None
        paths, parts = train_update(parallel, model, env_seed, on_batch=hook)
        history.append(path_adr(paths, env_cfg.gamma))
        seconds = {k: seconds[k] + parts[k] for k in seconds}
    data = io.BytesIO()
    model.save(data)
    row = dict(env=env, method=method, lam=lam, seed=seed, updates=cfg.updates,
               batch_decisions=cfg.batch_decisions,
               train_adr_last=float(np.mean(history[-max(1, len(history) // 10):])),
               gamma_d=float(model.gamma), seconds=sum(seconds.values()),
               **{f"seconds_{k}": v for k, v in seconds.items()})
    return row, data.getvalue()


def sb3_task(env: str, method: str, seed: int, cfg: Sb3StudyConfig, test_env_seed: int,
             policy_stream: np.random.SeedSequence) -> tuple[dict[str, Any], bytes]:
    """:func:`sb3_run`, then its final policy's test score (the policy sampling from
    ``policy_stream``)."""
    from stable_baselines3.common.utils import set_random_seed

    from repro.learn.sb3 import as_policy

    row, data = sb3_run(env, method, seed, cfg)
    from stable_baselines3 import PPO

    model = PPO.load(io.BytesIO(data), device="cpu")
    set_random_seed(int(policy_stream.generate_state(1)[0]))
    return {**row, **test_score(env, as_policy(model), cfg, test_env_seed)}, data


def sb3_runs(cmd: Command[Sb3StudyConfig], root: Path) -> pd.DataFrame:
    """Train (or reuse) every SB3 run; one row per run with its test score."""
    cfg, seed = cmd.study, cmd.seed
    wanted = [(env, method, s) for env in ENVS for method in METHODS if method.startswith("sb3")
              for s in range(seed, seed + cfg.seeds)]
    rows: dict[tuple, dict] = {}
    tasks = []
    for env, method, s in wanted:
        folder = root / env / f"{method}-seed{s}"
        if (folder / RESULT).exists():
            kept = json.loads((folder / RESULT).read_text())
            if kept["settings"] != sb3_settings(cfg, env, method, s):
                raise UsageError("--runs-dir", "a folder without runs of other settings",
                                 str(folder))
            rows[(env, method, s)] = kept["row"]
            continue
        tasks.append((env, method, s, cfg, test_env_seed(seed, env),
                      policy_stream(seed, env, method, s)))
    # a round of tasks at a time, each run's files written as its round ends: an interrupted
    # study loses at most the round in flight
    size = cmd.workers.processes
    for start in range(0, len(tasks), size):
        chunk = tasks[start:start + size]
        for task, (row, data) in zip(chunk, map_tasks(sb3_task, chunk, cmd.workers)):
            env, method, s = task[:3]
            folder = root / env / f"{method}-seed{s}"
            folder.mkdir(parents=True, exist_ok=True)
            write_bytes(folder / MODEL, data)
            write_json(folder / RESULT, dict(settings=sb3_settings(cfg, env, method, s), row=row))
            rows[(env, method, s)] = row
    return pd.DataFrame([{**rows[key], "run": str(root / key[0] / f"{key[1]}-seed{key[2]}")}
                         for key in wanted])


def trpo_jobs(cfg: Sb3StudyConfig, env: str, seed: int) -> list[TrainJob]:
    """The PS-TRPO runs of ``env`` (in the folder ``env`` of the study's runs)."""
    return [TrainJob(f"ps-trpo-mgae-seed{s}",
                     train_config("quick", env, "authors", seed=s, epochs=cfg.updates,
                                  batch_decisions=cfg.batch_decisions, lam=lam_of(env)),
                     env_config(env))
            for s in range(seed, seed + cfg.seeds)]


def trpo_runs(cmd: Command[Sb3StudyConfig], root: Path) -> pd.DataFrame:
    """Train (or resume) the PS-TRPO runs with the sweep machinery and test them."""
    from repro.runs.run_folder import CHECKPOINT
    from repro.learn.trained_policy import policy_from_checkpoint

    cfg, seed = cmd.study, cmd.seed
    rows = []
    for env in ENVS:
        jobs = trpo_jobs(cfg, env, seed)
        folders = run_sweep(jobs, root / env, cmd.workers)
        for job, folder in zip(jobs, folders):
            progress = pd.read_csv(folder / "progress.csv")
            stream = policy_stream(seed, env, "ps-trpo-mgae", job.train.seed)
            policy = policy_from_checkpoint(folder / CHECKPOINT, np.random.default_rng(stream))
            last = progress.average_discounted_return.iloc[-max(1, len(progress) // 10):]
            rows.append(dict(env=env, method="ps-trpo-mgae", lam=job.train.lam,
                             seed=job.train.seed, updates=cfg.updates,
                             batch_decisions=cfg.batch_decisions,
                             train_adr_last=float(last.mean()), gamma_d=float("nan"),
                             seconds=float(progress.seconds_sim.sum()
                                           + progress.seconds_update.sum()),
                             **test_score(env, policy, cfg, test_env_seed(seed, env)),
                             run=str(folder)))
    return pd.DataFrame(rows)


def heuristic_rows(cfg: Sb3StudyConfig, seed: int) -> pd.DataFrame:
    """Each environment's heuristic on its test episodes (one row each, seed -1: untrained)."""
    from repro.envs.bus.policies import no_holding
    from repro.envs.wildfire.policies import POLICIES

    rows = []
    for env in ENVS:
        rng = np.random.default_rng(policy_stream(seed, env, "heuristic", -1))
        policy = POLICIES["nearest"](rng) if env == "wildfire" else no_holding
        rows.append(dict(env=env, method=HEURISTICS[env], lam=lam_of(env), seed=-1, updates=0,
                         batch_decisions=0,
                         **test_score(env, policy, cfg, test_env_seed(seed, env)), run=""))
    return pd.DataFrame(rows)


def summarise(runs: pd.DataFrame, n_boot: int, seed: int) -> pd.DataFrame:
    """Per environment and method: mean, SEM, IQM and a 95% bootstrap CI of the mean over runs (a
    heuristic, tested once: its mean +- 1.96 SEM over paths); where its CI lies against PS-TRPO's;
    and for SB3 with M-GAE, the share of the gap from SB3's GAE to PS-TRPO that it closes, with a
    bootstrap CI (every method's runs resampled)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_BOOT_STREAM,)))
    rows = []
    for (env, method), grp in runs.groupby(["env", "method"], sort=False):
        x = grp.score.to_numpy()
        if len(x) > 1:
            _, lo, hi = bootstrap_ci(x, np.mean, n_boot=n_boot, rng=rng)
        else:
            lo, hi = x[0] - 1.96 * grp.score_sem.iloc[0], x[0] + 1.96 * grp.score_sem.iloc[0]
        rows.append(dict(env=env, method=method, n_runs=len(x), mean=float(x.mean()),
                         sem=sem(x) if len(x) > 1 else float(grp.score_sem.iloc[0]),
                         iqm=float(iqm(x)), ci_low=lo, ci_high=hi))
    table = pd.DataFrame(rows)
    ref = table[table.method == "ps-trpo-mgae"].set_index("env")
    table["vs_ps_trpo"] = ["" if r.method == "ps-trpo-mgae" else ci_side(r, ref.loc[r.env])
                           for r in table.itertuples()]
    table["gap_closed"] = table["gap_low"] = table["gap_high"] = np.nan
    for env in table.env.unique():
        score = {m: runs[(runs.env == env) & (runs.method == m)].score.to_numpy()
                 for m in METHODS}
        point = gap_closed(*(score[m].mean() for m in METHODS))
        draws = [gap_closed(*(rng.choice(score[m], len(score[m])).mean() for m in METHODS))
                 for _ in range(n_boot)]
        at = (table.env == env) & (table.method == "sb3-ppo-mgae")
        table.loc[at, ["gap_closed", "gap_low", "gap_high"]] = (
            point, *np.nanpercentile(draws, [2.5, 97.5]))
    return table


def gap_closed(gae: float, mgae: float, trpo: float) -> float:
    """(M-GAE - GAE) / (PS-TRPO - GAE): 1 when SB3 with M-GAE reaches PS-TRPO, 0 when it stays
    at SB3's own GAE; NaN when there is no gap."""
    return (mgae - gae) / (trpo - gae) if trpo != gae else float("nan")


def plot(runs: pd.DataFrame, summary: pd.DataFrame, stem: Path, title: str,
         sources: list[Path]) -> None:
    """One panel per environment: each run's test ADR (dots) and the mean with its 95% CI per
    method; the heuristic a dashed line with its band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(ENVS), figsize=(4.6 * len(ENVS), 4.2), squeeze=False)
    for ax, env in zip(axes[0], ENVS):
        s = summary[summary.env == env].set_index("method")
        for i, method in enumerate(METHODS):
            row = s.loc[method]
            dots = runs[(runs.env == env) & (runs.method == method)].score
            ax.plot(np.full(len(dots), i - 0.12), dots, ".", color=f"C{i}", alpha=0.5, ms=5)
            ax.errorbar([i + 0.06], [row["mean"]], yerr=[[row["mean"] - row.ci_low],
                                                        [row.ci_high - row["mean"]]],
                        fmt="o", color=f"C{i}", capsize=4)
        h = s.loc[HEURISTICS[env]]
        ax.axhline(h["mean"], color="0.4", ls="--", lw=1, label=HEURISTICS[env])
        ax.axhspan(h.ci_low, h.ci_high, color="0.4", alpha=0.15)
        ax.set_xticks(range(len(METHODS)), [m.replace("-", "\n", 1) for m in METHODS],
                      fontsize=8)
        ax.set_xlim(-0.6, len(METHODS) - 0.4)
        gap = s.loc["sb3-ppo-mgae"]
        ax.set_title(f"{env} (lambda = {lam_of(env):g}); M-GAE closes {gap.gap_closed:.0%} "
                     f"[{gap.gap_low:.0%}, {gap.gap_high:.0%}] of the gap", fontsize=8)
        ax.set_ylabel("test ADR, mean over runs\nerror bars: 95% bootstrap CI")
        ax.legend(fontsize=8, loc="best")
        ax.grid(True, alpha=0.3)
    fig.suptitle(title, fontsize=9)
    save_figure(fig, stem, sources)


def title(cfg: Sb3StudyConfig, scale: str) -> str:
    return (f"SB3 PPO with its GAE and with M-GAE vs PS-TRPO (M-GAE), {scale} scale: "
            f"{cfg.seeds} seeds x {cfg.updates} updates x {cfg.batch_decisions:,} decisions; "
            f"test ADR on {cfg.test_episodes:,} episodes")


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_study_arguments(p, Sb3StudyConfig, ("seeds", "updates", "batch_decisions"))
    add_replot(p)


def replot(cfg: Sb3StudyConfig, folders: Folders) -> int:
    """``--replot``: the figure from the CSVs, titled with the settings their sidecar records."""
    names = ("beyond_sb3.csv", "beyond_sb3_summary.csv")
    runs, summary = read_for_replot(folders, *names)
    prov = read_provenance(folders.results / names[0])
    figures, sources = replot_figures(folders, *names)
    plot(runs, summary, figures / "beyond_sb3", title(
        from_recorded(Sb3StudyConfig, prov["config"]), prov["scale"]), sources)
    print(f"wrote {figures / 'beyond_sb3'}.png/.pdf")
    return 0


def configure(args: argparse.Namespace) -> Command[Sb3StudyConfig]:
    return Command.of(args, for_scale(Sb3StudyConfig, args.scale, **given_fields(
        args, Sb3StudyConfig, ("seeds", "updates", "batch_decisions"))))


def run(cmd: Command[Sb3StudyConfig], folders: Folders) -> int:
    cfg, scale, seed = cmd.study, folders.scale, cmd.seed
    if cmd.replot:
        return replot(cfg, folders)
    results, figures = folders.open()
    root = folders.run_root("beyond-sb3")
    t0 = time.perf_counter()
    # the PS-TRPO runs of both environments first, in one pool (then SB3's, on the same workers)
    run_sweeps([(trpo_jobs(cfg, env, seed), root / env) for env in ENVS], cmd.workers)
    runs = pd.concat([sb3_runs(cmd, root), trpo_runs(cmd, root),
                      heuristic_rows(cfg, seed)], ignore_index=True)[list(COLUMNS)]
    summary = summarise(runs, cfg.n_boot, seed)
    prov = provenance(dataclasses.asdict(cfg), command="beyond-sb3", scale=scale,
                      seed=seed, wall_seconds=time.perf_counter() - t0)
    sources = [write_result(results / "beyond_sb3.csv", runs, prov),
               write_result(results / "beyond_sb3_summary.csv", summary, prov)]
    plot(runs, summary, figures / "beyond_sb3", title(cfg, scale), sources)
    print(summary.to_string(index=False))
    return 0
