"""``bench-learn``: seconds per training epoch split into simulation and update (TRPO + baseline),
at about 1,000 episodes per epoch: where an epoch's time goes, and which part bounds training
(docs/performance.md gives the measured balance).

Two tables: ``bench_learn.csv``, the trainer's own timing of each epoch (wall seconds, as in a run's
progress.csv), and ``bench_learn_pieces.csv``, what each piece of an epoch costs: after the timed
epochs, one batch of the next epoch is sampled and every piece of the epoch is repeated on it
(median thread CPU seconds over ``repeats`` rounds of calls), with the TRPO step also taken apart.
The suite's learner (``--learner suite``) writes ``bench_learn_suite.csv`` and
``bench_learn_suite_pieces.csv``, so both learners' tables stand side by side.
"""

from __future__ import annotations

import argparse
import copy
import tempfile
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, ClassVar

import numpy as np
import pandas as pd

from repro.core.config import Validated, add_config_arguments, for_scale, given_fields, to_dict
from repro.envs import BUILT_IN, env_package
from repro.learn.config import DEFAULT_LEARNER, LEARNERS, TrainConfig, learner_stem, train_config
from repro.learn.m_gae import m_gae_paths
from repro.learn.process import configure_process
from repro.runs.provenance import provenance
from repro.runs.results import write_result
from repro.runs.run_folder import TIMING_COLUMNS, config_dict
from repro.studies.kit.environments import add_chosen_env_arguments
from repro.studies.kit.options import Command, Folders, add_common

if TYPE_CHECKING:
    from repro.learn.trainer import Trainer


@dataclass(frozen=True)
class BenchConfig(Validated):
    """Size of the timing run."""

    episodes: int = 1000
    """Episodes per epoch."""
    epochs: int = 3
    """Epochs timed (the first includes numba compilation of cached kernels if not yet cached)."""
    repeats: int = 15
    """Rounds of calls of every piece on the last batch; each piece's median is reported."""

    SCALES: ClassVar[dict[str, dict[str, Any]]] = {
        "smoke": dict(episodes=100, epochs=1, repeats=1),
        "quick": {},
        "paper": dict(epochs=5),
    }

    def validate(self) -> None:
        self.check(self.episodes >= 1, "episodes", "an integer >= 1")
        self.check(self.epochs >= 1, "epochs", "an integer >= 1")
        self.check(self.repeats >= 1, "repeats", "an integer >= 1")


def median_cpu_seconds(fns: list[Callable[[], Any]], repeats: int) -> list[float]:
    """Median thread CPU time of ``repeats`` calls of each of ``fns``, called in turn, round after
    round, so that a slow spell of the machine (a shared VM's are seconds long) touches them all
    alike. Thread time: every piece computes on this one thread."""
    times = np.empty((repeats, len(fns)))
    for r in range(repeats):
        for i, fn in enumerate(fns):
            t0 = time.thread_time()
            fn()
            times[r, i] = time.thread_time() - t0
    return np.median(times, axis=0).tolist()


def epoch_pieces(tr: Trainer, repeats: int) -> pd.DataFrame:
    """What each piece of the run's next epoch costs (the run itself is left as it was).

    A learner that does not normalise observations standardises them all the same (with mean 0
    and variance 1), so it has that piece but no normaliser update.

    Columns: ``part`` (simulation; update, whose rows add up to the epoch's update; or trpo, the
    TRPO step's parts), ``piece``, ``calls`` per epoch, ``seconds`` per call, ``seconds_per_epoch``,
    ``us_per_decision`` and ``vs_simulation`` (seconds per epoch over the simulation's)."""
    from repro.learn import network, policy, trainer, trpo  # torch: once the options are checked

    cfg, env = tr.cfg, tr.env

    def sample():
        # a fresh generator with the same seed each time: every call samples the same batch
        sampler = policy.Sampler(tr.policy, tr.normalizer, np.random.default_rng(cfg.seed))
        return env.rollout(sampler, cfg.batch_episodes, trainer.epoch_seed(cfg.seed, tr.epoch))

    ro = sample()
    z, index = tr.normalizer(ro.obs), ro.step_index()
    values = tr.baseline.predict(z, index)
    adv, ret = m_gae_paths(ro.rewards, ro.durations, values, ro.path_start, env.gamma, cfg.lam)
    net = network.TanhMLP(tr.policy.net)
    theta = net.get_flat()
    obs, actions, adv_n = z, ro.actions, trpo.normalize(adv)
    rows = tr.fvp_rows(ro.n_decisions)
    fwd = net.forward(obs)
    grad = trpo.surrogate_gradient(net, fwd, actions, adv_n)
    fvp = trpo.fisher_vector_product(net, fwd if rows is None else fwd.rows(rows), cfg.cg_damping)

    def step():
        stats = trpo.trpo_step(net, obs, actions, adv_n, max_kl=cfg.max_kl, cg_iters=cfg.cg_iters,
                               cg_damping=cfg.cg_damping, backtrack_ratio=cfg.backtrack_ratio,
                               max_backtracks=cfg.max_backtracks, fvp_rows=rows)
        net.set_flat(theta)
        return stats

    trials = min(step().backtracks + 1, cfg.max_backtracks)
    pieces = [
        ("simulation", "rollout (engine and policy)", 1, sample),
        ("update", "normalise observations", 2, lambda: tr.normalizer(ro.obs)),
        ("update", "baseline predict", 1, lambda: tr.baseline.predict(z, index)),
        ("update", "M-GAE", 1, lambda: m_gae_paths(ro.rewards, ro.durations, values,
                                                   ro.path_start, env.gamma, cfg.lam)),
        ("update", "TRPO step", 1, step),
        *([("update", "normaliser update", 1,
            lambda: copy.deepcopy(tr.normalizer).update(ro.obs))] if cfg.normalize_obs else []),
        ("update", "baseline fit", 1, lambda: copy.deepcopy(tr.baseline).fit(z, index, ret)),
        ("trpo", "forward pass and log-probabilities", 1,
         lambda: net.forward(obs).log_probs()),
        ("trpo", "surrogate gradient", 1,
         lambda: trpo.surrogate_gradient(net, fwd, actions, adv_n)),
        ("trpo", f"conjugate gradient ({cfg.cg_iters} Fisher-vector products)", 1,
         lambda: trpo.conjugate_gradient(fvp, grad, cfg.cg_iters)),
        ("trpo", "Fisher-vector product (for the step size)", 1, lambda: fvp(grad)),
        ("trpo", "line-search trial", trials,
         lambda: trpo.surrogate_and_kl(net, fwd, actions, adv_n)),
    ]
    return timed(pieces, repeats, ro.n_decisions)


def timed(pieces: list[tuple[str, str, int, Callable[[], Any]]], repeats: int,
          n_decisions: int) -> pd.DataFrame:
    """The table of :func:`epoch_pieces`: each piece (part, name, calls per epoch, the call)
    timed, against an epoch of ``n_decisions`` decisions and the first piece, the simulation."""
    table = pd.DataFrame([piece[:3] for piece in pieces], columns=["part", "piece", "calls"])
    table["seconds"] = median_cpu_seconds([piece[3] for piece in pieces], repeats)
    table["seconds_per_epoch"] = table.calls * table.seconds
    table["us_per_decision"] = 1e6 * table.seconds_per_epoch / n_decisions
    table["vs_simulation"] = table.seconds_per_epoch / table.seconds_per_epoch[0]
    table.insert(0, "decisions", n_decisions)
    return table


VARIANTS = ("env",)
"""The option that chooses the environment benchmarked, not the benchmark's settings
(:func:`repro.studies.kit.options.scale_departures`)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_common(p, figures=False)
    p.add_argument("--env", default="toy", help="environment: " + ", ".join(BUILT_IN)
                   + ", or an importable module that provides the environment contract")
    p.add_argument("--learner", default=DEFAULT_LEARNER, choices=tuple(LEARNERS),
                   help="named learner whose network and Fisher products are timed: "
                        + ", ".join(LEARNERS) + " (default %(default)s; its batch is counted in "
                        "episodes here)")
    add_config_arguments(p, BenchConfig)


def extend_arguments(p: argparse.ArgumentParser, argv: list[str]) -> None:
    add_chosen_env_arguments(p, argv if "--env" in argv else [*argv, "--env", "toy"])


@dataclass(frozen=True)
class LearnBench:
    """What ``bench-learn`` times: its sizes, and the training run it times the epochs of."""

    bench: BenchConfig
    """The sizes (epochs, episodes per epoch, repeats of each piece)."""
    env: str
    """The environment's name (``--env``)."""
    learner: str
    """The named learner whose network and Fisher products are timed (``--learner``)."""
    train: TrainConfig
    """The training run: the named learner's (``--learner``), its batch counted in episodes."""
    env_config: Any
    """The environment's config, as its options give it."""


def configure(args: argparse.Namespace) -> Command[LearnBench]:
    cfg = for_scale(BenchConfig, args.scale, **given_fields(args, BenchConfig))
    train_cfg = train_config("quick", args.env, args.learner, seed=args.seed, epochs=cfg.epochs,
                             batch_episodes=cfg.episodes)
    return Command.of(args, LearnBench(bench=cfg, env=args.env, learner=args.learner,
                                       train=train_cfg,
                                       env_config=env_package(args.env).config_from_args(args)))


def run(cmd: Command[LearnBench], folders: Folders) -> int:
    setup = cmd.study
    cfg, train_cfg, env_cfg = setup.bench, setup.train, setup.env_config
    pkg = env_package(setup.env)
    results = folders.open_results()
    configure_process()  # as in training
    from repro.learn.trainer import Trainer  # torch: imported once the options are checked

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:  # checkpoints are written, as in a real run
        run = Trainer(train_cfg, pkg.make_env(env_cfg), out, env_cfg)
        frame = run.train()
    pieces = epoch_pieces(run, cfg.repeats)
    wall = time.perf_counter() - t0
    table = frame[["epoch", "batch_episodes", "decisions", *TIMING_COLUMNS]].copy()
    table.insert(0, "env", setup.env)
    table["update_share"] = table.seconds_update / (table.seconds_sim + table.seconds_update)
    pieces.insert(0, "env", setup.env)
    prov = provenance({"bench": to_dict(cfg), "train": to_dict(train_cfg),
                       "env": config_dict(env_cfg)},
                      command="bench-learn", scale=folders.scale, seed=cmd.seed,
                      wall_seconds=wall)
    stem = learner_stem("bench_learn", setup.learner)
    write_result(results / f"{stem}.csv", table, prov)
    write_result(results / f"{stem}_pieces.csv", pieces, prov)
    print(table.to_string(index=False))
    print(pieces.to_string(index=False))
    return 0
