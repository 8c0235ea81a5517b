"""A training run's folder and the promises it keeps.

A run folder holds ``config.json`` (the settings that determine the run), ``progress.csv`` (one row
per finished epoch), ``checkpoint.pt`` (everything needed to go on), ``policies/epochNNNN.pt`` (the
policy after each of the run's last :data:`KEPT_POLICIES` epochs, a checkpoint holding what acting
needs), ``kernels.json`` (the CPU kernels its epochs are trained with,
:func:`repro.runs.kernels.record`) and, while a process trains in it, ``run.lock``. A trainer
starts or resumes its run with :func:`start`, hands each epoch to :func:`record_epoch` and ends
with :func:`finish`; it writes nothing itself.

- **Safe to load.** A checkpoint holds only tensors, numbers and strings (the run's config and the
  sampler's generator state as JSON) and is read with ``torch.load(weights_only=True)``, which
  refuses anything else: a crafted file cannot run code, it is refused as unreadable.
- **Same run, same bytes.** torch names a checkpoint's zip records after the file it writes, and
  atomic writes go to a randomly named temporary file; serialising into memory first gives
  identical runs identical checkpoints.
- **One writer.** ``run.lock`` is held with ``flock`` and names its holder (pid, host); a second
  writer is refused, naming the holder. The kernel releases the lock when its process dies, so a
  lock left by a killed run is taken over by the next one.
- **Exact resume at every kill point.** Epoch e's row is appended to progress.csv before epoch e is
  checkpointed, and a (re)started run first cuts progress.csv back to its checkpoint's epochs (all
  of it when there is no checkpoint yet). So whichever write a kill interrupts, running the same
  command again ends with the files of an uninterrupted run. Temporary files of interrupted atomic
  writes are removed then too.
- **One set of kernels.** A run is resumed only under the kernels its epochs were trained with:
  resuming under others (a machine without the pin, ``REPRO_NATIVE_KERNELS`` set or unset) is
  refused, because the epochs after the resume would carry other bits than an uninterrupted run's.
  A run from before the folder recorded its kernels is taken at its finished call's record
  (``progress.provenance.json``), and with a :class:`~repro.runs.kernels.KernelWarning` when it
  has none.
- **Damage is one line.** An unreadable ``config.json`` or checkpoint, a checkpoint of another run,
  or a progress table missing checkpointed rows is refused (exit status 2) naming the file and what
  to do, before anything in the folder is changed.

torch is imported by the functions that read and write checkpoints, not by this module: a command
that only names a run folder's files checks its options without importing torch.
"""

from __future__ import annotations

import dataclasses
import io
import json
import warnings
from contextlib import AbstractContextManager
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from repro.core.config import to_dict
from repro.core.errors import UsageError, require
from repro.runs.files import append_csv, write_bytes, write_csv, write_json, write_text
from repro.runs.kernels import (SAME_BITS, KernelWarning, describe as describe_kernels,
                                record as kernel_record)
from repro.runs.locks import folder_lock, is_locked
from repro.runs.provenance import provenance

CONFIG = "config.json"
PROGRESS = "progress.csv"
PROVENANCE = "progress.provenance.json"
CHECKPOINT = "checkpoint.pt"
KERNELS = "kernels.json"
LOCK = "run.lock"
KEPT = "policies"
KEPT_POLICIES = 40
"""The policies after each of a run's last this-many epochs are kept in ``policies/`` (a few kB
each): the released runner's evaluation scores the snapshots of iterations 260-299 of 300."""
PROGRESS_COLUMNS = [
    "epoch", "average_return", "average_discounted_return", "kl", "entropy", "surrogate_before",
    "surrogate_after", "backtracks", "accepted", "explained_variance", "baseline_loss",
    "batch_episodes", "distinct_episodes", "decisions", "truncated_episodes", "seconds_sim",
    "seconds_trpo", "seconds_baseline", "seconds_update", "seconds",
]
"""The columns of progress.csv, one row per epoch. ``distinct_episodes``: how many of the batch's
episodes are distinct, drawn from distinct random stream positions (every one with the independent
sampler; the released pool's batch holds copies: :mod:`repro.learn.pool`). ``truncated_episodes``:
the batch's episodes
cut at the environment's bound on their length (``Rollout.truncated``; the wildfire's decision
limit), so that a policy that drifts into it is seen. Timing (wall seconds): ``seconds_sim`` the
rollout; ``seconds_trpo`` everything from the batch to the TRPO step's end (standardisation,
baseline prediction, M-GAE, the step); ``seconds_baseline`` the normaliser's update, the
standardisation in its new moments and the baseline's fit; ``seconds_update`` the last two
together; ``seconds`` the epoch (without writing its row and checkpoint). ``bench-learn`` times
the pieces one by one."""
TIMING_COLUMNS = [c for c in PROGRESS_COLUMNS if c.startswith("seconds")]
CHECKPOINT_FORMAT = 2
"""Version of the checkpoint's layout; 1 (before it was safe to load) held numpy objects."""
_JSON_FIELDS = ("run_config", "sampler_rng")
"""Checkpoint entries stored as JSON strings (nested dicts with 128-bit integers in the case of the
generator state, which ``weights_only`` loading would not take as they are)."""


# --- checkpoints ---------------------------------------------------------------------------------

def save_checkpoint(path: str | Path, state: dict[str, Any]) -> None:
    """Write ``state`` (tensors, numbers, strings, and the JSON-able entries of ``_JSON_FIELDS``)
    atomically, the same bytes for the same state."""
    encoded = {**state, "format": CHECKPOINT_FORMAT,
               **{k: json.dumps(state[k], sort_keys=True) for k in _JSON_FIELDS if k in state}}
    import torch

    buffer = io.BytesIO()
    torch.save(encoded, buffer)
    write_bytes(path, buffer.getvalue())


def load_checkpoint(path: str | Path, param: str = "--out", allowed: str | None = None, *,
                    obs_dim: int | None = None, n_actions: int | None = None,
                    training: bool = False) -> dict[str, Any]:
    """The state saved by :func:`save_checkpoint`, whole (:func:`state_problem`; with
    ``obs_dim`` and ``n_actions``, for an environment of those sizes; with ``training``, with
    what training on needs, not only a kept policy's acting state); anything else (a crafted
    pickle, a truncated, empty or random file, a folder, an older format, a loadable file with
    damaged contents) is a :class:`UsageError` naming ``param``."""
    import torch

    allowed = allowed or f"a readable {CHECKPOINT} of this suite (delete it to start the run again)"
    try:
        state = torch.load(path, weights_only=True)
        require(isinstance(state, dict) and state.get("format") == CHECKPOINT_FORMAT, param,
                allowed, str(path))
        state = {**state, **{k: json.loads(state[k]) for k in _JSON_FIELDS
                             if isinstance(state.get(k), str)}}
    except UsageError:
        raise
    except Exception:  # whatever torch or the unpickler raises for a file that is not ours
        raise UsageError(param, allowed, str(path)) from None
    problem = state_problem(state, obs_dim, n_actions, training)
    require(problem is None, param, f"{allowed}; {problem}",
            str(path) if isinstance(path, (str, Path)) else None)
    return state


ACTING_KEYS = ("epoch", "policy", "normalizer", "run_config")
"""The entries of a kept policy (besides ``format``): what acting needs."""
TRAINING_KEYS = ("baseline", "sampler_rng", "torch_rng")
"""The further entries of a run's checkpoint: what training on needs."""
POOL_KEYS = ("pool_offsets",)
"""The entries of a run on the released pool, besides those (its workers' stream positions)."""


def state_problem(state: dict[str, Any], obs_dim: int | None = None,
                  n_actions: int | None = None, training: bool = False) -> str | None:
    """What is wrong with a loaded checkpoint or kept policy, or None: every entry there (those of
    a checkpoint if ``training`` or if it has any) and of its type, a whole non-negative epoch, a
    run config with its hidden sizes, policy layers of those sizes (and of ``obs_dim`` inputs and
    ``n_actions`` outputs, if given), a normaliser and baseline of the policy's input size, finite
    numbers throughout, generator states numpy and torch take, and the released pool's worker
    positions where the run has one. Checked before anything uses the state, so that damage is
    one line, not a traceback halfway through a resume, an evaluation or a render."""
    whole = training or any(k in state for k in TRAINING_KEYS)
    missing = [k for k in ACTING_KEYS + (TRAINING_KEYS if whole else ()) if k not in state]
    if missing:
        return f"it lacks {', '.join(missing)}"
    unknown = sorted(map(str, set(state) - {"format", *ACTING_KEYS, *TRAINING_KEYS, *POOL_KEYS}))
    if unknown:
        return f"it holds entries this suite does not write: {', '.join(unknown)}"
    epoch, config = state["epoch"], state["run_config"]
    if not isinstance(epoch, int) or isinstance(epoch, bool) or epoch < 0:
        return f"its epoch is {epoch!r}, not a whole number >= 0"
    train = config.get("train") if isinstance(config, dict) else None
    hidden = train.get("hidden") if isinstance(train, dict) else None
    planned = train.get("epochs") if isinstance(train, dict) else None  # a kept policy has none
    if isinstance(planned, int) and epoch > planned:
        return f"its epoch is {epoch}, beyond its run's {planned} epochs"
    if (not isinstance(hidden, (list, tuple)) or not hidden
            or not all(isinstance(h, int) and h >= 1 for h in hidden)):
        return "its run config has no hidden layer sizes"
    problem, sizes = (_gru_problem(state["policy"], train, obs_dim, n_actions)
                      if train.get("policy", "mlp") == "gru" else
                      _policy_problem(state["policy"], list(hidden), obs_dim, n_actions))
    problem = problem or _normaliser_problem(state["normalizer"], sizes[0])
    if problem or not whole:
        return problem
    return _training_problem(state, train, sizes[0])


def _policy_problem(policy: Any, hidden: list[int], obs_dim: int | None,
                    n_actions: int | None) -> tuple[str | None, list[int]]:
    """What is wrong with a state's policy (:func:`state_problem`), and its layer sizes."""
    first = policy.get("net.0.weight") if isinstance(policy, dict) else None
    last = policy.get(f"net.{2 * len(hidden)}.weight") if isinstance(policy, dict) else None
    if not (_is_tensor(first, 2) and _is_tensor(last, 2)):
        return f"its policy is not an MLP of hidden sizes {hidden}", [0]
    sizes = [first.shape[1], *hidden, last.shape[0]]
    problem = _tensors_problem("policy", policy, _mlp_shapes(sizes))
    if problem:
        return problem, sizes
    for name, want, have in (("inputs", obs_dim, sizes[0]), ("actions", n_actions, sizes[-1])):
        if want is not None and have != want:
            return f"its policy has {have} {name}, the environment {want}", sizes
    return None, sizes


def _gru_problem(policy: Any, train: dict[str, Any], obs_dim: int | None,
                 n_actions: int | None) -> tuple[str | None, list[int]]:
    """What is wrong with a state's gru policy (``repro.learn.gru.GRUPolicy``, of the sizes its
    run config names), and [its observation size]."""
    hidden, features, output = (train.get(k) for k in ("gru_hidden", "gru_features",
                                                        "gru_feature_output"))
    first = policy.get("features.0.weight") if isinstance(policy, dict) else None
    out = policy.get("out.weight") if isinstance(policy, dict) else None
    if not (isinstance(hidden, int) and isinstance(output, int)
            and isinstance(features, (list, tuple)) and _is_tensor(first, 2)
            and _is_tensor(out, 2)):
        return "its policy is not the gru its run config names", [0]
    actions = out.shape[0]
    sizes = [first.shape[1], *features, output]
    expect = {**_mlp_shapes(sizes, "features", F64),
              "gru.x_weight": ((3 * hidden, output), F64),
              "gru.h_weight": ((3 * hidden, hidden), F64), "gru.bias": ((3 * hidden,), F64),
              "out.weight": ((actions, hidden), F64), "out.bias": ((actions,), F64)}
    d = first.shape[1] - actions
    problem = _tensors_problem("policy", policy, expect)
    for name, want, have in (("inputs", obs_dim, d), ("actions", n_actions, actions)):
        if problem is None and want is not None and have != want:
            problem = f"its policy has {have} {name}, the environment {want}"
    return problem, [d]


def _normaliser_problem(norm: Any, d: int) -> str | None:
    """What is wrong with a state's observation normaliser of ``d`` inputs."""
    count = norm.get("count") if isinstance(norm, dict) else None
    if not isinstance(count, int) or isinstance(count, bool) or count < 0:
        return "its normaliser has no count of observations"
    problem = _tensors_problem("normaliser", {k: v for k, v in norm.items() if k != "count"},
                               {"mean": ((d,), F64), "var": ((d,), F64)})
    if problem or bool((norm["var"] < 0).any()):
        return problem or "its normaliser has a negative variance"
    return None


def _training_problem(state: dict[str, Any], train: dict[str, Any], d: int) -> str | None:
    """What is wrong with what a checkpoint holds to train on: the baseline (of ``d`` inputs), the
    generator states and the released pool's worker positions."""
    import torch

    if train.get("baseline", "linear") == "mlp":
        expect = {**_mlp_shapes([d, *train.get("baseline_hidden", (32, 32)), 1]),
                  "target_mean": ((), F64), "target_std": ((), F64), "fitted": ((), "bool")}
    else:
        expect = {"coeffs": ((2 * d + 4,), F64)}
    problem = _tensors_problem("baseline", state["baseline"], expect)
    if problem:
        return problem
    try:
        np.random.default_rng().bit_generator.state = state["sampler_rng"]
    except Exception:  # numpy's setter raises ValueError, TypeError or KeyError
        return "its sampler's generator state is not one numpy takes"
    rng = state["torch_rng"]
    if not (isinstance(rng, torch.Tensor) and rng.dtype == torch.uint8
            and rng.shape == torch.get_rng_state().shape):
        return "its torch generator state is not one torch takes"
    if train.get("sampler") == "released-pool":
        offsets = state.get("pool_offsets")
        if not (isinstance(offsets, torch.Tensor) and offsets.dtype == torch.int64
                and tuple(offsets.shape) == (train.get("batch_workers"),)
                and bool((offsets >= 0).all())):
            return "its pool's worker positions are not one whole number >= 0 per worker"
    return None


def _is_tensor(x: Any, ndim: int) -> bool:
    import torch

    return isinstance(x, torch.Tensor) and x.dim() == ndim


F64 = "float64"
"""The dtype (its name in torch) of the normaliser's and the baselines' statistics."""
DTYPE = "float32"
"""The networks' dtype (:data:`repro.learn.policy.DTYPE`, which this layer cannot import)."""


def _mlp_shapes(sizes: list[int], prefix: str = "net",
                dtype: str = DTYPE) -> dict[str, tuple[tuple[int, ...], str]]:
    """The entries of an MLP of layer ``sizes`` (inputs first) named ``prefix``: each layer's
    weight and bias, in ``dtype`` (the networks' by default; the gru's are float64)."""
    return {**{f"{prefix}.{2 * i}.weight": ((b, a), dtype) for i, (a, b) in
               enumerate(zip(sizes, sizes[1:]))},
            **{f"{prefix}.{2 * i}.bias": ((b,), dtype) for i, b in enumerate(sizes[1:])}}


def _tensors_problem(what: str, tensors: Any,
                     shapes: dict[str, tuple[tuple[int, ...], str]]) -> str | None:
    """What is wrong with ``tensors`` (a dict of tensors with exactly the keys, shapes and dtypes,
    named as in torch, of ``shapes``, all finite), or None: a network saved in another dtype
    would act with other arithmetic than it was trained with."""
    import torch

    if not isinstance(tensors, dict) or set(tensors) != set(shapes):
        return f"its {what} does not have the entries {', '.join(sorted(shapes))}"
    for key, (shape, name) in shapes.items():
        t, dtype = tensors[key], getattr(torch, name)
        if not isinstance(t, torch.Tensor) or tuple(t.shape) != shape:
            got = tuple(t.shape) if isinstance(t, torch.Tensor) else type(t).__name__
            return f"its {what}'s {key} is {got}, not of shape {shape}"
        if t.dtype != dtype:
            return f"its {what}'s {key} is {t.dtype}, not {dtype} as trained"
        if t.dtype != torch.bool and not bool(torch.isfinite(t).all()):
            return f"its {what}'s {key} holds NaN or Inf"
    return None


# --- the run's identity --------------------------------------------------------------------------

def config_dict(cfg: Any) -> Any:
    """A dataclass config as a dict (other configs unchanged), for config.json and sidecars."""
    return to_dict(cfg) if dataclasses.is_dataclass(cfg) else cfg


def read_config(folder: Path, param: str = "--out") -> dict[str, Any] | None:
    """The run's ``config.json`` (None if it has none); an unreadable one is a UsageError."""
    return _read_object(folder / CONFIG, param)


def _read_object(path: Path, param: str) -> dict[str, Any] | None:
    """The JSON object in ``path`` (None if there is no such file); an unreadable one is a
    UsageError naming ``param`` and the file."""
    if not path.exists():
        return None
    try:
        saved = json.loads(path.read_text())
        if not isinstance(saved, dict):
            raise ValueError(saved)
        return saved
    except (OSError, ValueError):
        raise UsageError(param, f"a run folder with a readable {path.name} (repair or delete it)",
                         str(path)) from None


def run_difference(saved: dict[str, Any], mine: dict[str, Any], defaults: dict[str, Any],
                   aliases: dict[str, dict[str, str]] | None = None) -> str | None:
    """The first setting (other than ``train.epochs``) in which the run config ``saved`` differs
    from ``mine``, as "part.key: saved vs mine"; None if they are the same run. Settings that
    ``saved`` lacks were added to the code after the run started, so they held their defaults;
    ``aliases`` (part -> old key -> key) renames keys that ``saved`` spells the old way."""
    for part in sorted(set(saved) | set(mine)):
        a, b = saved.get(part), _as_json(mine.get(part))
        if isinstance(a, dict) and isinstance(b, dict):
            renamed = (aliases or {}).get(part, {})
            a = {**_as_json(defaults.get(part) or {}), **{renamed.get(k, k): v
                                                          for k, v in a.items()}}
            for key in sorted(set(a) | set(b)):
                if (part, key) != ("train", "epochs") and a.get(key) != b.get(key):
                    return f"{part}.{key}: {a.get(key)!r} there, {b.get(key)!r} here"
        elif a != b:
            return f"{part}: {a!r} there, {b!r} here"
    return None


def _as_json(value: Any) -> Any:
    return json.loads(json.dumps(value, default=str))


def is_new(folder: Path) -> bool:
    """Whether ``folder`` is missing or holds nothing but a lock or leftovers of interrupted writes
    (a folder of other files is not a run)."""
    ours = {LOCK, *(p.name for p in _leftovers(folder))}
    return not folder.is_dir() or all(p.name in ours for p in folder.iterdir())


def _leftovers(folder: Path) -> list[Path]:
    """Temporary files of atomic writes that a kill interrupted."""
    return [*folder.glob(".*.tmp*"), *(folder / KEPT).glob(".*.tmp*")]


def kept_policy_path(folder: Path, epoch: int) -> Path:
    """Where the policy after ``epoch`` (0-based) is kept (the folder is made if need be)."""
    (folder / KEPT).mkdir(exist_ok=True)
    return folder / KEPT / f"epoch{epoch:04d}.pt"


def kept_policies(folder: Path, last: int, epochs: int) -> list[Path]:
    """The kept policies after epochs ``epochs - last`` .. ``epochs - 1`` of a finished run
    (UsageError naming --runs-dir if one is missing: a run older than kept policies)."""
    paths = [Path(folder) / KEPT / f"epoch{e:04d}.pt" for e in range(epochs - last, epochs)]
    missing = [p for p in paths if not p.is_file()]
    require(not missing, "--runs-dir", f"run folders that kept their last {last} policies "
            "(retrain the run in a new --runs-dir)", str(missing[:1]))
    return paths


def check_same_run(folder: Path, mine: dict[str, Any], defaults: dict[str, Any],
                   param: str = "--out",
                   aliases: dict[str, dict[str, str]] | None = None) -> None:
    """Refuse (UsageError naming ``param``) a folder that is neither new nor a run with the
    settings ``mine`` (:func:`run_difference`); reads only."""
    saved = read_config(folder, param)
    if saved is None:
        require(is_new(folder), param, "new, empty or a run folder", str(folder))
        return
    diff = run_difference(saved, mine, defaults, aliases)
    require(diff is None, param, f"a run folder made with these settings ({CONFIG}: {diff})",
            str(folder))


# --- resuming ------------------------------------------------------------------------------------

def resume_state(folder: Path, mine: dict[str, Any], defaults: dict[str, Any],
                 param: str = "--out", *, obs_dim: int | None = None,
                 n_actions: int | None = None,
                 aliases: dict[str, dict[str, str]] | None = None) -> dict[str, Any] | None:
    """Check everything a (re)start needs, changing nothing: the folder holds this run (or none),
    its checkpoint (if any) is readable, whole (for an environment of ``obs_dim`` and
    ``n_actions``, if given) and of this run, and progress.csv holds its epochs. Returns the
    checkpoint's state, or None."""
    check_same_run(folder, mine, defaults, param, aliases)
    path = folder / CHECKPOINT
    if not path.exists():
        return None
    state = load_checkpoint(path, param, obs_dim=obs_dim, n_actions=n_actions, training=True)
    diff = run_difference(state.get("run_config") or {}, mine, defaults, aliases)
    require(diff is None, param, f"a run folder whose {CHECKPOINT} belongs to its run ({diff}; "
            f"delete {CHECKPOINT} to start again)", str(folder))
    rows = progress_rows(folder)
    epochs = int(state["epoch"])
    # one row more where a run stopped between an epoch's row and its checkpoint, never more
    require(epochs <= rows <= epochs + 1, param, f"a run folder whose {PROGRESS} holds the "
            f"{epochs} epochs of its {CHECKPOINT} (it holds {rows}; delete {CHECKPOINT} to start "
            "again)", str(folder))
    # a checkpoint never goes back: the last finished call left one of its epochs_after
    finished = (_read_object(folder / PROVENANCE, param) or {}).get("epochs_after")
    require(not isinstance(finished, int) or epochs >= finished, param, f"a run folder whose "
            f"{CHECKPOINT} holds the {finished} epochs its last call finished with (it holds "
            f"{epochs}; delete {CHECKPOINT} to start again)", str(folder))
    check_kernels(folder, param)
    return state


def recorded_kernels(folder: Path, param: str = "--out") -> dict[str, Any] | None:
    """The kernels the run in ``folder`` was trained with: its kernels.json, else (a run from
    before the folder kept one) what its last finished call recorded, else None."""
    kept = _read_object(folder / KERNELS, param)
    if kept is not None:
        return kept
    machine = (_read_object(folder / PROVENANCE, param) or {}).get("machine", {})
    kernels = machine.get("kernels") if isinstance(machine, dict) else None
    if not isinstance(kernels, dict):
        return None
    return describe_kernels(kernels, machine.get("cpu", "unknown"))


def kernels_in_todays_terms(folder: Path, param: str = "--out") -> dict[str, Any] | None:
    """The kernels the run in ``folder`` was trained with (:func:`recorded_kernels`), its
    arithmetic read as today's where that trains its policy to the same bits
    (:data:`~repro.runs.kernels.SAME_BITS`): equal to :func:`kernel_record` if and only if this
    process trains the run's epochs bit for bit as they were trained."""
    earlier = recorded_kernels(folder, param)
    policy = ((_read_object(folder / CONFIG, param) or {}).get("train") or {}).get("policy", "mlp")
    if earlier is not None and policy in SAME_BITS.get(earlier.get("arithmetic"), ()):
        earlier = {**earlier, "arithmetic": kernel_record()["arithmetic"]}
    return earlier


def check_kernels(folder: Path, param: str = "--out") -> None:
    """Refuse (UsageError naming ``param``) resuming the run in ``folder`` under other kernels than
    its epochs were trained with; warn where they are not recorded."""
    earlier, now = kernels_in_todays_terms(folder, param), kernel_record()
    if earlier is None:
        warnings.warn(f"{folder}: the kernels its epochs were trained with are not recorded (a run "
                      "from before the pin); resuming it may mix kernels", KernelWarning,
                      stacklevel=2)
        return
    changed = ", ".join(f"{key} {earlier.get(key)} -> {now.get(key)}"
                        for key in sorted(earlier.keys() | now.keys())
                        if earlier.get(key) != now.get(key))
    require(not changed, param, f"a run folder trained under the kernels it is resumed with "
            f"({KERNELS}: {changed}; resume it where and as it was trained, or train into a new "
            "folder)", str(folder))


def progress_rows(folder: Path) -> int:
    """The epochs the progress.csv of the run in ``folder`` holds (0 without one)."""
    path = folder / PROGRESS
    return max(len(path.read_text().splitlines()) - 1, 0) if path.exists() else 0


def restore(folder: Path, epochs: int, config: dict[str, Any],
            columns: list[str]) -> list[dict[str, Any]]:
    """Make ``folder`` the state an uninterrupted run has after ``epochs`` epochs: remove leftover
    temporary files, write ``config`` to config.json, cut progress.csv back to ``epochs`` rows
    (a row appended after the last checkpoint, whole or cut short, goes) in ``columns`` (a column
    that a run recorded before it existed is left empty in its rows). Returns those rows."""
    for leftover in _leftovers(folder):
        leftover.unlink()
    write_json(folder / CONFIG, config)
    path = folder / PROGRESS
    if epochs == 0:
        path.unlink(missing_ok=True)
        return []
    lines = path.read_text().splitlines(keepends=True)
    if len(lines) != epochs + 1:
        write_text(path, "".join(lines[:epochs + 1]))
    table = pd.read_csv(path)
    if list(table.columns) != columns:
        table = table.reindex(columns=columns)
        write_csv(path, table)
    return table.to_dict("records")


def start(folder: Path, config: dict[str, Any], defaults: dict[str, Any], columns: list[str],
          param: str = "--out", *, obs_dim: int | None = None, n_actions: int | None = None,
          aliases: dict[str, dict[str, str]] | None = None
          ) -> tuple[dict[str, Any] | None, list[dict[str, Any]]]:
    """Start or resume the run ``config`` in ``folder``: check the folder (changing nothing if
    it is refused, :func:`resume_state`), then bring it to the state of an uninterrupted run after
    its checkpoint's epochs (:func:`restore`). Returns the checkpoint's state (None for a new
    run) and the progress rows of those epochs. Only ``epochs`` may differ from the folder's run
    (to extend or finish it); its config.json keeps the larger number. ``aliases``: the old
    spellings the folder's config.json may carry (:func:`saved_run_aliases`)."""
    state = resume_state(folder, config, defaults, param, obs_dim=obs_dim, n_actions=n_actions,
                         aliases=aliases)
    epochs = 0 if state is None else int(state["epoch"])
    if state is not None:
        saved = state["run_config"]["train"].get("epochs", 0)
        config = {**config, "train": {**config["train"],
                                      "epochs": max(saved, config["train"]["epochs"])}}
    rows = restore(folder, epochs, config, columns)
    if state is None:
        write_json(folder / KERNELS, kernel_record())
    return state, rows


def record_epoch(folder: Path, row: dict[str, Any], columns: list[str], state: dict[str, Any],
                 epochs: int) -> None:
    """Record the epoch that brought the run to ``state`` (of ``epochs`` in all): its row in
    progress.csv, its policy in ``policies/`` if it is one of the last :data:`KEPT_POLICIES`,
    then the checkpoint. The row goes first, so that progress.csv never holds fewer rows than the
    checkpoint has epochs (a resumed run cuts off any more)."""
    append_row(folder, row, columns)
    if state["epoch"] > epochs - KEPT_POLICIES:
        save_checkpoint(kept_policy_path(folder, state["epoch"] - 1), acting_state(state))
    save_checkpoint(folder / CHECKPOINT, state)


def acting_state(state: dict[str, Any]) -> dict[str, Any]:
    """What acting needs of a run's state (:func:`~repro.learn.trained_policy.policy_from_state`):
    the policy and normaliser, and the run's config but its epoch count (which a run extended later
    changes), so that a kept policy has the bytes of an uninterrupted run's."""
    train = {k: v for k, v in state["run_config"]["train"].items() if k != "epochs"}
    return {**{k: state[k] for k in ACTING_KEYS},
            "run_config": {**state["run_config"], "train": train}}


def finish(folder: Path, config: dict[str, Any], seed: int, wall_seconds: float,
           epochs_before: int, epochs_after: int) -> None:
    """Write ``progress.provenance.json``, last: what this call trained (from ``epochs_before``
    to ``epochs_after``), from which commit, on what."""
    write_json(folder / PROVENANCE, provenance(
        config, command="train", scale=None, seed=seed, wall_seconds=wall_seconds,
        extra={"epochs_before": epochs_before, "epochs_after": epochs_after}))


def append_row(folder: Path, row: dict[str, Any], columns: list[str]) -> None:
    """Append one epoch's row to progress.csv (appended, because rewriting the table every epoch
    grows with the run: 0.18 s per epoch by epoch 1,550 of a paper-scale C6 run)."""
    append_csv(folder / PROGRESS, pd.DataFrame([row], columns=columns))


def epochs_done(folder: str | Path, param: str = "--runs-dir") -> int:
    """Epochs the checkpoint of the run in ``folder`` holds (0 if it has none); a damaged one is
    a UsageError naming ``param``, the option that named the folder (a sweep's)."""
    path = Path(folder) / CHECKPOINT
    return int(load_checkpoint(path, param)["epoch"]) if path.exists() else 0


def is_finished(folder: str | Path, epochs: int, param: str = "--runs-dir") -> bool:
    """Whether the run in ``folder`` has ``epochs`` epochs and its last ``train`` call ended
    (its provenance sidecar is written last, and no write was left half done)."""
    folder = Path(folder)
    return ((folder / PROVENANCE).exists() and not _leftovers(folder)
            and epochs_done(folder, param) >= epochs)


# --- one writer ----------------------------------------------------------------------------------

def writer_lock(folder: Path, param: str = "--out") -> AbstractContextManager[None]:
    """Hold ``folder``'s run.lock while the block runs; a UsageError naming the holder if another
    process holds it (:func:`repro.runs.locks.folder_lock`)."""
    return folder_lock(folder, LOCK, param, "a run folder")


def locked_by(folder: Path) -> str | None:
    """The holder of ``folder``'s run.lock if another process holds it now, else None."""
    return is_locked(folder, LOCK)
