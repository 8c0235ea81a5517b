"""The settings of one PS-TRPO + M-GAE run, each explained where it is defined.

Two learners are named (:data:`LEARNERS`): ``authors``, the released rllab runner that trained the
paper's policies, is the default; ``suite`` is this suite's own set-up (observation normalisation,
two hidden layers, orthogonal initialisation, Fisher subsampling, batches counted in episodes).
docs/semantics.md section 5.7 tables every setting with the released code's line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, ClassVar

from repro.core.config import (SCALES, Validated, add_config_arguments, flag, given_fields,
                               settings)
from repro.core.errors import require
from repro.envs import env_package, train_defaults
from repro.learn.m_gae import ESTIMATORS


@dataclass(frozen=True)
class TrainConfig(Validated):
    """Hyperparameters of one PS-TRPO + M-GAE run."""

    env: str = "toy"
    """Environment: a built-in one (toy, wildfire, bus) or an importable module
    (:func:`repro.envs.env_package`)."""
    epochs: int = 40
    """Policy updates; each samples a fresh batch."""
    batch_decisions: int | None = 12_000
    """Batch counted in decisions (the released runner's ``batch_size``, a sample being one agent's
    decision): whole episodes until the finished ones hold at least this many decisions, plus the
    episodes the other parallel workers have in flight then (:mod:`repro.learn.batch`). None:
    counted in episodes (``batch_episodes``). Exactly one of the two is set."""
    batch_workers: int = 40
    """Parallel sampling workers the decision-counted batch emulates (the released runner.sh's
    ``--n_parallel 40``): each finishes the episode it has in flight when the count is reached."""
    sampler: str = "independent"
    """Whose random streams the batch's episodes draw from (:data:`SAMPLERS`): "independent", every
    episode its own; "released-pool", the released runner's unseeded pool, batch_workers streams
    forked from one state, so that identical episodes recur (:mod:`repro.learn.pool`)."""
    batch_episodes: int | None = None
    """Batch counted in episodes: this many whole episodes per epoch (the paper's tables: bus 540,
    wildfire 600-1,200). None: counted in decisions (``batch_decisions``)."""
    lam: float = 1.0
    """M-GAE's lambda (the paper's lambda), any number >= 0. An advantage weights the residual of a
    decision made tau seconds later by e^{-gamma lam tau}, the paper's

        A^{M-GAE(gamma, lambda)}_k = sum_l exp(-gamma lam (T_{k+l} - T_k)) delta_{k+l}

    (docs/semantics.md section 5.3): lam scales the continuous-time discount rate, so values above
    1 are meaningful (later residuals weigh less than in the return; the bus trains with 2). It is
    not GAE's per-step lambda_d: with every duration 1 s, lambda_d = e^{-gamma (lam - 1)}. Named
    ``lam`` as ``lambda`` is Python's keyword; the name is serialised (config.json, run names such
    as ``lam2_batch540_seed0``, ``--lam``), so it stays."""
    advantage: str = "m-gae"
    """Advantage estimator (``repro.learn.m_gae.ESTIMATORS``; claim X1), m being the epoch's mean
    macro-action duration: "m-gae", the paper's M-GAE; "decision-gae", standard GAE with every
    macro-action one step, discount exp(-gamma m) and GAE lambda exp(-gamma (lam - 1) m), what a
    user of a standard library would do; "duration-gae", M-GAE's discount exp(-gamma dt) with that
    lambda constant per decision. Runs recorded before this setting existed used "m-gae"."""
    max_kl: float = 0.01
    """TRPO max step: bound on the mean KL between consecutive policies."""
    policy: str = "mlp"
    """The shared policy network (:data:`POLICIES`): "mlp", a categorical MLP of the agent's
    observation (``hidden``, ``init``; the paper's bus and wildfire curves); "gru", the released
    runner's recurrent policy (``--recurrent gru --feature_net``): a feature MLP of the observation
    and the agent's previous action, a GRU over the agent's own decisions, softmax logits
    (``gru_*``; :mod:`repro.learn.gru`), which drew the paper's bus arrival and load pictures."""
    hidden: tuple[int, ...] = (32,)
    """Hidden layer sizes of the policy MLP (tanh); the released runner's ``policy_hidden='32'``."""
    init: str = "xavier"
    """Initial weights of the policy MLP: "xavier" (Glorot-uniform weights, zero biases, as the
    released CategoricalMLPPolicy) or "orthogonal" (gain sqrt 2, the output layer's 0.01, zero
    biases: a nearly uniform first policy)."""
    gru_hidden: int = 32
    """Units of the gru policy's GRU (the released runner's ``--policy_hidden 32``)."""
    gru_features: tuple[int, ...] = (128, 64, 32)
    """Hidden layer sizes (tanh) of the gru policy's feature MLP (the released runner's
    ``--feature_hidden`` default)."""
    gru_feature_output: int = 16
    """Outputs (linear) of the gru policy's feature MLP, the GRU's input (``--feature_output``)."""
    gru_fvp: str = "finite-difference"
    """How the gru's TRPO step computes Fisher-vector products (:data:`GRU_FVPS`):
    "finite-difference", the released ``FiniteDifferenceHvp``: the KL's gradient at theta +- eps v,
    eps = gru_fvp_eps / (|theta| + 1e-8); "exact", the exact product J' M J v."""
    gru_fvp_eps: float = 1e-5
    """Base step of the finite-difference products (the released ``base_eps``, 1e-5)."""
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
    fvp_subsample: float = 1.0
    """Fraction of the batch's decisions (drawn without replacement, afresh each epoch) on which
    the Fisher-vector products are computed; 1 = all (exact, the released runner). rllab's
    ``subsample_factor``; OpenAI Baselines' TRPO uses every 5th decision."""
    normalize_obs: bool = False
    """Running mean/std observation normalisation (frozen within a batch); the released runner has
    none."""
    seed: int = 0
    """Root of every random stream of the run."""

    SCALES: ClassVar[dict[str, dict[str, Any]]] = {
        "smoke": dict(epochs=2, batch_episodes=8, batch_decisions=300, batch_workers=4),
        "quick": {},
        "paper": {},
    }
    BEFORE_ADDED: ClassVar[dict[str, Any]] = dict(init="orthogonal", batch_decisions=None)
    """What runs recorded before these settings existed used: the suite's learner."""

    ALIASES: ClassVar[dict[str, str]] = {"obs_norm": "normalize_obs"}
    """Older flags (``--obs-norm``, ``--no-obs-norm``), still taken."""

    def validate(self) -> None:
        self.check(isinstance(self.env, str) and self.env != "", "env", "an environment name")
        self.check(self.epochs >= 1, "epochs", "an integer >= 1")
        self.check((self.batch_decisions is None) != (self.batch_episodes is None),
                   "batch_decisions", "given instead of --batch-episodes, not with it")
        self.check(self.batch_decisions is None or self.batch_decisions >= 1, "batch_decisions",
                   "an integer >= 1")
        self.check(self.batch_episodes is None or self.batch_episodes >= 1, "batch_episodes",
                   "an integer >= 1")
        self.check(self.batch_workers >= 1, "batch_workers", "an integer >= 1")
        self.check(self.sampler in SAMPLERS, "sampler", "one of " + ", ".join(SAMPLERS))
        self.check(self.sampler == "independent" or self.batch_decisions is not None, "sampler",
                   "independent when the batch is counted in episodes (--batch-episodes)")
        self.check(self.init in INITS, "init", "one of " + ", ".join(INITS))
        self.check(self.lam >= 0 and math.isfinite(self.lam), "lam", "a number >= 0")
        self.check(self.advantage in ESTIMATORS, "advantage", "one of " + ", ".join(ESTIMATORS))
        self.check(self.max_kl > 0 and math.isfinite(self.max_kl), "max_kl", "a number > 0")
        self.check(len(self.hidden) >= 1 and min(self.hidden) >= 1, "hidden",
                   "one or more positive layer sizes")
        self.check(self.policy in POLICIES, "policy", "one of " + ", ".join(POLICIES))
        if self.policy == "mlp":
            for name in GRU_FIELDS:
                self.check(getattr(self, name) == getattr(TrainConfig, name), name,
                           f"{getattr(TrainConfig, name)!r} (its default) with --policy mlp: "
                           "a setting of the gru policy")
        self.check(self.gru_hidden >= 1, "gru_hidden", "an integer >= 1")
        self.check(len(self.gru_features) >= 1 and min(self.gru_features) >= 1, "gru_features",
                   "one or more positive layer sizes")
        self.check(self.gru_feature_output >= 1, "gru_feature_output", "an integer >= 1")
        self.check(self.gru_fvp in GRU_FVPS, "gru_fvp", "one of " + ", ".join(GRU_FVPS))
        self.check(self.gru_fvp_eps > 0 and math.isfinite(self.gru_fvp_eps), "gru_fvp_eps",
                   "a number > 0")
        self.check(self.policy != "gru" or self.fvp_subsample == 1, "fvp_subsample",
                   "1 with --policy gru (its Fisher products run over whole agent paths)")
        self.check(self.baseline in BASELINES, "baseline", "one of " + ", ".join(BASELINES))
        self.check(len(self.baseline_hidden) >= 1 and min(self.baseline_hidden) >= 1,
                   "baseline_hidden", "one or more positive layer sizes")
        self.check(self.baseline_iters >= 1, "baseline_iters", "an integer >= 1")
        self.check(self.cg_iters >= 1, "cg_iters", "an integer >= 1")
        self.check(self.cg_damping >= 0, "cg_damping", ">= 0")
        self.check(0 < self.backtrack_ratio < 1, "backtrack_ratio", "in (0, 1)")
        self.check(0 < self.fvp_subsample <= 1, "fvp_subsample", "in (0, 1]")
        self.check(self.max_backtracks >= 1, "max_backtracks", "an integer >= 1")
        self.check(self.seed >= 0, "seed", "an integer >= 0")


INITS = ("xavier", "orthogonal")
BASELINES = ("linear", "mlp")
"""The value baselines (``TrainConfig.baseline``; :func:`repro.learn.baseline.make_baseline`)."""
POLICIES = ("mlp", "gru")
"""The policy networks (``TrainConfig.policy``)."""
GRU_FVPS = ("finite-difference", "exact")
"""The gru's Fisher-vector products (``TrainConfig.gru_fvp``)."""
GRU_FIELDS = ("gru_hidden", "gru_features", "gru_feature_output", "gru_fvp", "gru_fvp_eps")
"""The TrainConfig settings of the gru policy only."""
MLP_FIELDS = ("hidden", "init")
"""The TrainConfig settings of the mlp policy only: a named learner sets them for both policies,
and with --policy gru a value other than the learner's is refused (the gru's settings, other
than their defaults, are refused with --policy mlp)."""
SAMPLERS = ("independent", "released-pool")
"""The batch samplers (``TrainConfig.sampler``)."""

AUTHORS = TrainConfig()
"""The released rllab runner that trained the paper's policies (FirestormProject/runners/
rurllab.py, runner.sh): TrainConfig's defaults, one hidden layer of 32, Glorot-uniform weights, no
observation normalisation, every decision in the Fisher products, the batch counted in
decisions."""
SUITE = replace(AUTHORS, hidden=(32, 32), init="orthogonal", normalize_obs=True,
                fvp_subsample=0.2, batch_decisions=None,
                batch_episodes=train_defaults(env_package(AUTHORS.env))["batch_episodes"])
"""This suite's set-up before the authors' was derived: observation normalisation, two hidden
layers, orthogonal initialisation, a fifth of the decisions for the Fisher products and the batch
counted in episodes, the environment's (the paper's episode counts)."""
LEARNERS: dict[str, TrainConfig] = {"authors": AUTHORS, "suite": SUITE}
"""The named learners. A run's config is its learner's, then the environment's training defaults
(``TRAIN_DEFAULTS``), the scale's sizes and the user's settings (:func:`train_config`). Both use
the linear feature baseline, centred advantages and rllab's conjugate-gradient constants."""
BATCH_UNITS = ("batch_decisions", "batch_episodes")
"""The two units a batch is counted in: exactly one of these fields is set."""
LEARNER_FIELDS = tuple(f for f in settings(TrainConfig) if f not in BATCH_UNITS
                       and getattr(SUITE, f) != getattr(AUTHORS, f))
"""The TrainConfig fields, besides the batch's unit, in which the named learners differ."""
DEFAULT_LEARNER = "authors"


def batch_unit(cfg: TrainConfig) -> str:
    """The field ``cfg``'s batch is counted in: "batch_decisions" or "batch_episodes"."""
    return BATCH_UNITS[cfg.batch_decisions is None]


def learner_suffix(learner: str) -> tuple[str, ...]:
    """The part of a result's file stem that names a learner other than the default: ``("suite",)``
    or nothing."""
    return () if learner == DEFAULT_LEARNER else (learner,)


def learner_label(learner: str) -> str:
    """A named learner in prose: "the authors' learner", "the suite's learner"."""
    owner = f"{learner}'" if learner.endswith("s") else f"{learner}'s"
    return f"the {owner} learner"


def learner_stem(stem: str, learner: str) -> str:
    """A study's result file stem for ``learner``: ``stem``, then ``_suite`` for the suite's."""
    return "_".join((stem, *learner_suffix(learner)))


def learner_name(cfg: TrainConfig) -> str:
    """The named learner whose settings ``cfg`` has (its batch's unit included), else "custom"."""
    for name, preset in LEARNERS.items():
        if (all(getattr(cfg, f) == getattr(preset, f) for f in LEARNER_FIELDS)
                and getattr(cfg, batch_unit(preset)) is not None):
            return name
    return "custom"


def train_config(scale: str, env: str, learner: str = DEFAULT_LEARNER,
                 **overrides: Any) -> TrainConfig:
    """The config at ``scale`` for ``env``: the learner's (:data:`LEARNERS`), then the
    environment's training defaults (the paper's settings), the scale's sizes and the explicit
    overrides (``None`` means not given).

    The batch is counted in the learner's unit unless the overrides give a size in the other one
    (``batch_episodes`` for the authors' learner: counted in episodes)."""
    require(scale in SCALES, "--scale", "one of " + ", ".join(SCALES), scale)
    require(learner in LEARNERS, "--learner", "one of " + ", ".join(LEARNERS), learner)
    preset = LEARNERS[learner]
    given = {k: v for k, v in overrides.items() if v is not None}
    base = {**{f: getattr(preset, f) for f in settings(TrainConfig)},
            **train_defaults(env_package(env)), **TrainConfig.SCALES[scale]}
    if given.get("policy") == "gru":  # the mlp's settings as set without flags (a run's
        for name in MLP_FIELDS:       # config.json gives them) or refused
            require(given.get(name, base[name]) == base[name], flag(name), "left out with "
                    "--policy gru (a setting of the mlp policy)", given.get(name))
    fields = {**base, "env": env, **given}
    require(not all(u in given for u in BATCH_UNITS), "--batch-decisions",
            "given instead of --batch-episodes, not with it", given.get("batch_decisions"))
    unit = next((u for u in BATCH_UNITS if u in given), batch_unit(preset))
    fields[next(u for u in BATCH_UNITS if u != unit)] = None
    return TrainConfig(**fields)


def study_train_config(scale: str, env: str, learner: str, batch_decisions: int,
                       batch_episodes: int, settings: tuple[tuple[str, Any], ...] = (),
                       **fields: Any) -> TrainConfig:
    """A study's TrainConfig: the study sizes its batch in both units, the learner counts it in
    its own (:func:`batch_unit`); ``settings``, (field, value) pairs, override
    the learner's (a batch size among them also sets the unit)."""
    unit = batch_unit(LEARNERS[learner])
    size = batch_decisions if unit == "batch_decisions" else batch_episodes
    sized = {"batch_decisions", "batch_episodes"} & {k for k, _ in settings}
    batch = {} if sized else {unit: size}
    return train_config(scale, env, learner, **batch, **dict(settings), **fields)


SETTING_FIELDS = (*LEARNER_FIELDS, "batch_decisions", "batch_episodes", "batch_workers", "sampler")
"""The learner settings a study may change one at a time (``settings`` of a study config)."""


def setting_tag(field: str, value: Any) -> str:
    """A file-name-safe tag of one learner setting, e.g. ``hidden32x32``, ``normalizeobs1``."""
    if isinstance(value, (tuple, list)):
        text = "x".join(str(v) for v in value)
    elif isinstance(value, bool):
        text = str(int(value))
    else:
        text = f"{value:g}" if isinstance(value, float) else str(value)
    return field.replace("_", "") + text


def add_learner_option(p: Any, writes: str) -> None:
    """A study's ``--learner``; ``writes`` names the results another learner than the default
    writes (e.g. ``"beyond_mgae_suite*"``)."""
    p.add_argument("--learner", choices=tuple(LEARNERS), help="named learner: "
                   + ", ".join(LEARNERS)
                   + f" (default {DEFAULT_LEARNER}: the released runner; suite writes {writes})")


def add_study_learner_arguments(p: Any, writes: str) -> None:
    """A study's ``--learner`` (:func:`add_learner_option`) and its batch size in either unit (the
    learner uses its own)."""
    add_learner_option(p, writes)
    p.add_argument("--batch-decisions", type=int,
                   help="training decisions per epoch, with a learner that counts them "
                        "(paper: 12000)")
    p.add_argument("--batch-episodes", type=int,
                   help="training episodes per epoch, with a learner that counts them (paper: 600)")


def add_learner_arguments(p: Any) -> None:
    """``--learner`` and a flag for every TrainConfig setting (each overrides the named learner's,
    the environment's and the scale's value of that setting; docs/semantics.md section 5.7).
    Studies take :func:`add_study_learner_arguments`."""
    p.add_argument("--learner", default=DEFAULT_LEARNER, choices=tuple(LEARNERS),
                   help="named learner: " + ", ".join(LEARNERS) + " (default %(default)s: the "
                        "released runner that trained the paper's policies)")
    add_config_arguments(p, TrainConfig, show_defaults=False)
    shown = resolved_defaults()
    for action in p._actions:
        if action.dest in shown:
            action.help = f"{action.help} (default: {shown[action.dest]})".replace("%", "%%")


def resolved_defaults(scale: str = "quick") -> dict[str, str]:
    """Each TrainConfig setting's value where no flag gives it (:func:`train_config` at ``scale``),
    as ``train --help`` shows it: one value, or one per learner, per built-in environment, or both,
    where they differ."""
    from repro.envs import BUILT_IN

    def shown(value: Any) -> str:
        return " ".join(map(str, value)) if isinstance(value, tuple) else str(value)

    configs = {(learner, env): train_config(scale, env, learner)
               for learner in LEARNERS for env in BUILT_IN}
    out = {}
    for name in settings(TrainConfig):
        if name == "env":
            continue
        values = {key: shown(getattr(cfg, name)) for key, cfg in configs.items()}
        if len(set(values.values())) == 1:
            out[name] = next(iter(values.values()))
            continue
        if all(len({values[lrn, env] for lrn in LEARNERS}) == 1 for env in BUILT_IN):
            out[name] = ", ".join(f"{env} {values[DEFAULT_LEARNER, env]}" for env in BUILT_IN)
            continue
        by_learner = []
        for learner in LEARNERS:
            mine = {env: v for (lrn, env), v in values.items() if lrn == learner}
            text = (next(iter(mine.values())) if len(set(mine.values())) == 1 else
                    ", ".join(f"{env} {v}" for env, v in mine.items()))
            by_learner.append(f"{learner}: {text}")
        out[name] = "; ".join(by_learner)
    return out


def learner_overrides(args: Any) -> dict[str, Any]:
    """The train_config arguments of :func:`add_learner_arguments`'s options: the learner, and
    the settings given."""
    return dict(learner=args.learner, **given_fields(args, TrainConfig))
