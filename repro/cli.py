"""``python -m repro <command>``: the one entry point; Makefile targets are thin wrappers over it.

Each command lives in its own module, which defines ``add_arguments(parser)``, ``configure(args)``
and ``run``: the parsed options are read once, by ``configure``, into the command's frozen settings
(a driver's: a :class:`~repro.studies.kit.options.Command` of its study's config), and a driver (a
command with ``--scale``) is called as ``run(settings, folders)``, its folders resolved here once
(:class:`~repro.studies.kit.options.Folders`), any other command as ``run(settings)``. Nothing below
``configure`` sees the parsed options.
Only the module of the command being run is imported, and the command modules import torch,
matplotlib and scipy's heavier parts inside the functions that compute with them, so a bad flag or
value is refused in well under a second of CPU time (tests/test_cli_startup.py checks that torch
and matplotlib are not imported by then).
"""

from __future__ import annotations

import argparse
import errno
import importlib
import sys
from typing import Any

from repro.core.config import flat_settings, read_config_file
from repro.core.errors import UsageError, WorkerDied, require
from repro.runs.files import check_names
from repro.runs.results import release_results
from repro.studies.kit.options import Folders, note_scale_departures

S = "repro.studies."
COMMANDS: dict[str, tuple[str, str]] = {
    # does a policy trained on fixed steps transfer to event-driven simulation, and why?
    "transfer": (S + "transfer.transfer", "train on ED and FS simulators, test on ED (C8, C9)"),
    "transfer-heuristics": (S + "transfer.heuristics",
                            "heuristics' ADR on the transfer study's test episodes (C8, C9)"),
    "transfer-dt": (S + "transfer.dt_grid",
                    "transfer to ED against dT on a log grid, race rate beside it (X3)"),
    "transfer-order": (S + "transfer.order", "C9 under both same-instant orders (X4)"),
    "transfer-ablation": (S + "transfer.learner_ablation",
                          "transfer to ED, one learner setting at a time from the authors' (X5)"),
    "transfer-inputs": (S + "transfer.c9_inputs",
                        "C9's policies tested with out-of-range inputs clamped (the mechanism)"),
    # does the learned bus holding beat the baselines, as the paper's figures show?
    "bus-thresholds": (S + "bus.thresholds",
                       "Optimized Thresholds by differential evolution (bus baseline)"),
    "bus-lambda": (S + "bus.lambda_curves",
                   "bus training curves over lambda, with the baselines (C1, C2)"),
    "bus-batch": (S + "bus.batch_curves",
                  "bus training curves over the batch size, with the baselines (C3)"),
    "bus-arrivals": (S + "bus.arrivals", "bus arrival-time figure per policy"),
    "bus-loads": (S + "bus.loads", "bus 4th-cycle load figure per policy (C4)"),
    "bus-eval": (S + "bus.evaluate", "evaluate a bus policy (return, loads, regularity)"),
    # when do fixed steps cause races, and what does event-driven simulation save?
    "race": (S + "races.race", "race-condition Monte Carlo table and figure (C10)"),
    "wildfire-races": (S + "races.wildfire_races",
                       "races in the wildfire simulator, dT against N (X2)"),
    "scaling": (S + "races.scaling", "event-driven vs time-stepped compute against N (C11)"),
    # how does a learned wildfire policy behave?
    "wildfire-behaviour": (S + "wildfire.behaviour",
                           "frequencies of a long ED-trained policy vs the flowchart (C6, C7)"),
    "wildfire-penalty": (S + "wildfire.penalty",
                         "the behaviour study over crowding penalties, as the authors measured it"
                         " (C6, C7)"),
    "wildfire-eval": (S + "wildfire.evaluate", "ADR of a heuristic wildfire policy"),
    "render": (S + "wildfire.render", "an animation (GIF) of one episode of a policy"),
    # training, and does M-GAE matter?
    "advantage-estimators": (S + "advantage.estimators",
                             "M-GAE against two other advantage estimators, bus and wildfire (X1)"),
    "advantage-sb3": (S + "advantage.sb3",
                      "SB3 PPO with its GAE and with M-GAE against PS-TRPO, bus and wildfire (X6)"),
    "train": (S + "training.train", "train a shared policy with PS-TRPO and M-GAE"),
    "plot-runs": (S + "training.plot_runs",
                  "training curves of run folders, runs grouped by setting, seed intervals"),
    # how fast are the engines and the learner?
    "bench-bus": (S + "bench.bus", "episodes/s of the fast and SimPy bus engines"),
    "bench-wildfire": (S + "bench.wildfire",
                       "decisions/s of the fast and SimPy wildfire engines (MLP policy)"),
    "bench-learn": (S + "bench.learn", "seconds per training epoch: simulation vs update"),
    # the verdicts, and how far their intervals can be trusted
    "claims": ("repro.claims", "render paper_claims.md from the result files"),
    "interval-coverage": (S + "verdicts.interval_coverage",
                          "coverage of the claims' interval kinds at 3, 5 and 10 runs"),
    "reproduce": ("repro.reproduce", "every study at --scale, their runs trained together, then "
                  "the verdicts"),
}
"""command -> (module, one-line description)."""
ALIASES: dict[str, str] = {
    "table-race": "race",
    "table-thresholds": "bus-thresholds",
    "fig-scaling": "scaling",
    "fig-transfer": "transfer",
    "wildfire-heuristics": "transfer-heuristics",
    "beyond-transfer-dt": "transfer-dt",
    "beyond-order": "transfer-order",
    "learner-ablation": "transfer-ablation",
    "c9-inputs": "transfer-inputs",
    "fig-bus-lambda": "bus-lambda",
    "fig-bus-batch": "bus-batch",
    "fig-bus-arrivals": "bus-arrivals",
    "fig-bus-load": "bus-loads",
    "beyond-races": "wildfire-races",
    "beyond-mgae": "advantage-estimators",
    "beyond-sb3": "advantage-sb3",
}
"""Every other name of a command (the paper's names of its tables and figures, and the names the
commands had before they were grouped by question) -> the command. The Makefile has a target of
each (tests/test_make.py checks it), and ``python -m repro --help`` lists them."""


DISK_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM,
               errno.ENAMETOOLONG)
"""Failures to write that are the machine's, not the suite's: reported in one line (exit 1)."""
PATH_OPTIONS = ("out", "results_dir", "figures_dir", "runs_dir", "checkpoint", "mlp_run")
"""Options that name a file or folder (by their ``args`` names): checked for length and encoding
before a command runs, whichever of them it has."""

SIZE_LIMITS = {
    "seeds": 1000, "n_jobs": 1024, "epochs": 10**6, "final_epochs": 10**6,
    "test_episodes": 10**7, "episodes": 10**7, "fast_episodes": 10**7,
    "reference_episodes": 10**7, "repeats": 10**4, "fps": 1000, "frames": 10**5,
    "bisection_steps": 1000, "popsize": 10**5, "maxiter": 10**5, "max_decisions": 10**7,
}
"""The largest value of each size option (by its ``args`` name), checked before a command runs:
far above any study's (the paper scale's largest is 2,000 test episodes, 500 epochs, 20 seeds)
and below what would run for years or overflow a counter. Every other integer option, the seed
included, is at most :data:`INT64_MAX` (numpy's and numba's integers)."""
INT64_MAX = 2**63 - 1


def check_sizes(args: argparse.Namespace) -> None:
    """Refuse (UsageError naming the flag) an integer option above its :data:`SIZE_LIMITS` entry,
    or any above :data:`INT64_MAX`, one value at a time for a list."""
    for dest, value in vars(args).items():
        values = value if isinstance(value, (list, tuple)) else [value]
        limit = SIZE_LIMITS.get(dest, INT64_MAX)
        for v in values:
            if isinstance(v, int) and not isinstance(v, bool):
                require(v <= limit, "--" + dest.replace("_", "-"), f"an integer <= {limit:,}",
                        v if v < 10**20 else f"{str(v)[:6]}... ({len(str(v))} digits)")


def file_argv(parser: argparse.ArgumentParser, settings: dict[str, Any], argv: list[str],
              path: str, partial: bool = False) -> tuple[list[str], dict[str, str]]:
    """The command-line tokens of a config file's ``settings`` (:func:`read_config_file`) for
    ``parser``, leaving out those ``argv`` gives (flags override the file), and each such flag's
    key in the file. A key is a setting's field name or flag, an old spelling included; a key no
    option of ``parser`` takes (unless ``partial``: options may still be added), or a value of
    the wrong type, is a UsageError naming the key and what is allowed."""
    options = {o: a for o, a in parser._option_string_actions.items()
               if o.startswith("--") and a.dest not in ("help", "config")}
    tokens: list[str] = []
    keys: dict[str, str] = {}
    seen: dict[str, str] = {}  # dest -> the key that gave it
    for key, value in settings.items():
        option = "--" + str(key).removeprefix("--").replace("_", "-")
        action = options.get(option)
        if action is None:
            require(partial, f"{path}: {key}", "a setting of this command: " + ", ".join(
                sorted({o.removeprefix("--") for o, a in options.items()
                        if o == "--" + a.dest.replace("_", "-")})))
            continue
        require(action.dest not in seen, f"{path}: {key}",
                f"given once (the file also gives it as {seen.get(action.dest)})")
        seen[action.dest] = key
        keys.update(dict.fromkeys(action.option_strings, key))
        if any(t == o or t.startswith(o + "=") for t in argv for o in action.option_strings):
            continue
        tokens += _tokens(action, option, value, f"{path}: {key}")
    return tokens, keys


def _tokens(action: argparse.Action, option: str, value: Any, param: str) -> list[str]:
    """The tokens that give ``action`` the value ``value`` (refused if of the wrong type)."""
    if action.nargs == 0:  # a switch: true gives its flag; false its --no- form, or nothing
        require(isinstance(value, bool), param, "true or false", value)
        if value or not isinstance(action, argparse.BooleanOptionalAction):
            return [option] if value else []
        negative = option.startswith("--no-")
        return ["--" + option.removeprefix("--no-") if negative else "--no-" + option[2:]]
    if value is None:
        return [option, "none"] if getattr(action.type, "optional", False) else []
    values = list(value) if isinstance(value, (list, tuple)) else [value]
    many = action.nargs in ("+", "*") or isinstance(action, argparse._AppendAction)
    require(many or len(values) == 1, param, "one value", value)
    allowed = getattr(action.type, "allowed", f"a value {option} takes")
    for v in values:
        require(not isinstance(v, (bool, dict, list)), param, allowed, v)
        # an option of text (a path, a name) takes text only: the number 5 is no folder name
        require(action.type is not None or isinstance(v, str), param, "a string", v)
        try:
            parsed = v if action.type is None else action.type(str(v))
        except (ValueError, TypeError, argparse.ArgumentTypeError):
            raise UsageError(param, allowed, v) from None
        require(action.choices is None or parsed in action.choices, param,
                "one of " + ", ".join(map(str, action.choices or ())), v)
    if isinstance(action, argparse._AppendAction):
        return [t for v in values for t in (option, str(v))]
    return [option, *map(str, values)]


class OneLineParser(argparse.ArgumentParser):
    """argparse whose errors are one line on stderr and exit status 2, and which takes no
    abbreviation of an option (``--epoch 2`` is refused, not taken for ``--epochs 2``)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, allow_abbrev=False, **kwargs)

    def error(self, message: str) -> None:  # type: ignore[override]
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        raise SystemExit(2)


def parse_arguments(module: Any, parser: argparse.ArgumentParser,
                    argv: list[str]) -> tuple[argparse.Namespace, dict[str, str]]:
    """The command's arguments: ``--config FILE``'s settings (:func:`file_argv`), then ``argv``
    (flags given override the file); and each flag the file gave, as "FILE: key", so that a bad
    value is named by its key there."""
    parser.add_argument("--config", metavar="FILE",
                        help="a JSON or TOML file of settings (a run's config.json, or keys named "
                             "as this command's flags); flags given override it")
    pre = OneLineParser(prog=parser.prog, add_help=False)
    pre.add_argument("--config")
    path = pre.parse_known_args(argv)[0].config
    data = read_config_file(path) if path else {}
    # a run's config.json: what it held for settings that did not exist yet (train)
    if hasattr(module, "saved_settings"):
        data = module.saved_settings(data)
    settings = flat_settings(data, path)
    # options that depend on other options (train: the chosen environment's own options)
    if hasattr(module, "extend_arguments"):
        module.extend_arguments(parser, file_argv(parser, settings, argv, path, True)[0] + argv)
    tokens, keys = file_argv(parser, settings, argv, path)
    show_defaults(parser)
    return parser.parse_args(tokens + argv), {flag: f"{path}: {key}" for flag, key in keys.items()}


def spelled_as_given(parser: argparse.ArgumentParser, argv: list[str]) -> dict[str, str]:
    """Each option's first flag -> the other spelling of it that ``argv`` gives (an old
    spelling, such as ``--simulator`` for ``--only``), so that an error names the flag the user
    typed."""
    out = {}
    for action in parser._actions:
        for option in action.option_strings[1:]:
            if any(t == option or t.startswith(option + "=") for t in argv):
                out[action.option_strings[0]] = option
    return out


def show_defaults(parser: argparse.ArgumentParser) -> None:
    """End the help of every option that has a default, and does not say it yet, with it (a
    switch's default, off, goes unsaid)."""
    for action in parser._actions:
        default = action.default
        if (action.help and "default" not in action.help and default not in (None, False, [])
                and default is not argparse.SUPPRESS and action.nargs != 0):
            action.help += " (default: %(default)s)"


def command_module(name: str) -> Any:
    """The module of the command ``name`` (or of one of its other names), imported."""
    return importlib.import_module(COMMANDS[ALIASES.get(name, name)][0])


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        usage = "usage: python -m repro <command> [options]\n\ncommands:\n" + "".join(
            f"  {name:<20} {desc}\n" for name, (_, desc) in COMMANDS.items()) + (
            "\nother names:\n" + "".join(f"  {old:<20} {new}\n" for old, new in ALIASES.items()))
        # asked for: the standard output; a missing command is an error
        print(usage, end="", file=sys.stdout if argv else sys.stderr)
        return 0 if argv else 2
    typed = argv[0]  # the name the user gave (messages use it), maybe an alias
    name = ALIASES.get(typed, typed)
    if name not in COMMANDS:
        print(f"repro: error: command: must be one of {', '.join([*COMMANDS, *ALIASES])}, got "
              f"{typed!r}", file=sys.stderr)
        return 2
    module = command_module(name)
    parser = OneLineParser(prog=f"repro {typed}", description=COMMANDS[name][1])
    keys: dict[str, str] = {}  # flag -> "FILE: key" of the --config file that gave it
    try:
        module.add_arguments(parser)
        args, keys = parse_arguments(module, parser, argv[1:])
        keys = {**spelled_as_given(parser, argv[1:]), **keys}
        # every seed becomes a numpy SeedSequence, which takes no negative entropy
        if getattr(args, "seed", None) is not None and args.seed < 0:
            raise UsageError("--seed", "an integer >= 0", args.seed)
        check_sizes(args)
        for dest in PATH_OPTIONS:
            if isinstance(getattr(args, dest, None), str):
                param = "--" + dest.replace("_", "-")
                require(getattr(args, dest).strip() != "", param, "a path (not empty)",
                        getattr(args, dest))
                check_names(getattr(args, dest), param)
        folders = Folders.of(args)  # a driver's, the one place its folders are read
        note_scale_departures(module, parser, args)
        config = module.configure(args)  # the module's settings: nothing below here reads args
        return int((module.run(config) if folders is None else module.run(config, folders)) or 0)
    except UsageError as err:
        if err.param in keys:  # named as given: an old spelling, or a key of the --config file
            err = UsageError(keys[err.param], err.allowed, err.got)
        print(f"repro {typed}: error: {err}", file=sys.stderr)
        return 2
    except WorkerDied as err:
        print(f"repro {typed}: error: {err}", file=sys.stderr)
        return 1
    except OSError as err:
        # a full or read-only disk, or a folder without permission: the system's reason, one line
        if err.errno not in DISK_ERRORS:
            raise
        where = "" if err.filename is None else f": {err.filename}"
        print(f"repro {typed}: error: {err.strerror}{where}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"repro {typed}: interrupted; the same command resumes a training run or sweep from "
              "its last checkpoint", file=sys.stderr)
        return 130
    finally:
        release_results()  # the results folder a driver held (repro.runs.results.open_results)
