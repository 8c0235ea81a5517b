"""``python -m repro <command>``: the one entry point; Makefile targets are thin wrappers over it.

Each command lives in its own module, which defines ``add_arguments(parser)`` and ``run(args)``.
Only the module of the command being run is imported, so the CLI starts quickly.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import sys
from typing import Any

from repro.core.config import flat_settings, read_config_file
from repro.core.errors import UsageError, WorkerDied, require
from repro.core.io import check_names, release_results
from repro.experiments.options import default_folders

COMMANDS: dict[str, tuple[str, str]] = {
    "race": ("repro.experiments.race", "race-condition Monte Carlo table and figure (C10)"),
    "bus-eval": ("repro.experiments.bus_eval", "evaluate a bus policy (return, loads, regularity)"),
    "bus-thresholds": ("repro.experiments.bus_thresholds",
                       "Optimized Thresholds by differential evolution (bus baseline)"),
    "fig-bus-arrivals": ("repro.experiments.fig_bus_arrivals",
                         "bus arrival-time figure per policy"),
    "fig-bus-load": ("repro.experiments.fig_bus_load", "bus 4th-cycle load figure per policy (C4)"),
    "fig-bus-lambda": ("repro.experiments.fig_bus_lambda",
                       "bus training curves over lambda, with the baselines (C1, C2)"),
    "fig-bus-batch": ("repro.experiments.fig_bus_batch",
                      "bus training curves over the batch size, with the baselines (C3)"),
    "bench-bus": ("repro.experiments.bench_bus", "episodes/s of the fast and SimPy bus engines"),
    "wildfire-eval": ("repro.experiments.wildfire_eval", "ADR of a heuristic wildfire policy"),
    "bench-wildfire": ("repro.experiments.bench_wildfire",
                       "decisions/s of the fast and SimPy wildfire engines (MLP policy)"),
    "scaling": ("repro.experiments.scaling",
                "event-driven vs time-stepped compute against N (C11)"),
    "fig-transfer": ("repro.experiments.transfer",
                     "train on ED and FS simulators, test on ED (C8, C9)"),
    "wildfire-heuristics": ("repro.experiments.wildfire_heuristics",
                            "heuristics' ADR on the transfer study's test episodes (C8, C9)"),
    "wildfire-behaviour": ("repro.experiments.wildfire_behaviour",
                           "frequencies of a long ED-trained policy vs the flowchart (C6, C7)"),
    "beyond-mgae": ("repro.experiments.beyond_mgae",
                    "M-GAE against two other advantage estimators, bus and wildfire (X1)"),
    "beyond-sb3": ("repro.experiments.beyond_sb3",
                   "SB3 PPO with its GAE and with M-GAE against PS-TRPO, bus and wildfire"),
    "beyond-transfer-dt": ("repro.experiments.transfer_dt",
                           "transfer to ED against dT on a log grid, race rate beside it (X3)"),
    "beyond-races": ("repro.experiments.beyond_races",
                     "races in the wildfire simulator, dT against N (X2)"),
    "learner-ablation": ("repro.experiments.learner_ablation",
                         "transfer to ED, one learner setting at a time from the authors' (X5)"),
    "c9-inputs": ("repro.experiments.c9_inputs",
                  "C9's policies tested with out-of-range inputs clamped (the mechanism)"),
    "beyond-order": ("repro.experiments.beyond_order",
                     "C9 under both same-instant orders (X4)"),
    "claims": ("repro.claims", "render paper_claims.md from the result files"),
    "train": ("repro.experiments.train", "train a shared policy with PS-TRPO and M-GAE"),
    "render": ("repro.experiments.render", "an animation (GIF) of one episode of a policy"),
    "bench-learn": ("repro.experiments.bench_learn",
                    "seconds per training epoch: simulation vs update"),
    "plot-runs": ("repro.experiments.plot_runs",
                  "training curves of run folders, runs grouped by setting, seed intervals"),
}
"""command -> (module, one-line description)."""


DISK_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM,
               errno.ENAMETOOLONG)
"""Failures to write that are the machine's, not the suite's: reported in one line (exit 1)."""
PATH_OPTIONS = ("out", "results_dir", "figures_dir", "runs_dir", "checkpoint", "mlp_run")
"""Options that name a file or folder (by their ``args`` names): checked for length and encoding
before a command runs, whichever of them it has."""


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
    """argparse whose errors are one line on stderr and exit status 2."""

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
    return parser.parse_args(tokens + argv), {flag: f"{path}: {key}" for flag, key in keys.items()}


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        usage = "usage: python -m repro <command> [options]\n\ncommands:\n" + "".join(
            f"  {name:<18} {desc}\n" for name, (_, desc) in COMMANDS.items())
        # asked for: the standard output; a missing command is an error
        print(usage, end="", file=sys.stdout if argv else sys.stderr)
        return 0 if argv else 2
    name = argv[0]
    if name not in COMMANDS:
        print(f"repro: error: command: must be one of {', '.join(COMMANDS)}, got {name!r}",
              file=sys.stderr)
        return 2
    module = importlib.import_module(COMMANDS[name][0])
    parser = OneLineParser(prog=f"repro {name}", description=COMMANDS[name][1])
    keys: dict[str, str] = {}  # flag -> "FILE: key" of the --config file that gave it
    try:
        module.add_arguments(parser)
        args, keys = parse_arguments(module, parser, argv[1:])
        # every seed becomes a numpy SeedSequence, which takes no negative entropy
        if getattr(args, "seed", None) is not None and args.seed < 0:
            raise UsageError("--seed", "an integer >= 0", args.seed)
        for dest in PATH_OPTIONS:
            if isinstance(getattr(args, dest, None), str):
                check_names(getattr(args, dest), "--" + dest.replace("_", "-"))
        default_folders(args)
        return int(module.run(args) or 0)
    except UsageError as err:
        if err.param in keys:  # a bad value from the --config file: named by its key there
            err = UsageError(keys[err.param], err.allowed, err.got)
        print(f"repro {name}: error: {err}", file=sys.stderr)
        return 2
    except WorkerDied as err:
        print(f"repro {name}: error: {err}", file=sys.stderr)
        return 1
    except OSError as err:
        # a full or read-only disk, or a folder without permission: the system's reason, one line
        if err.errno not in DISK_ERRORS:
            raise
        where = "" if err.filename is None else f": {err.filename}"
        print(f"repro {name}: error: {err.strerror}{where}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"repro {name}: interrupted; the same command resumes a training run or sweep from "
              "its last checkpoint", file=sys.stderr)
        return 130
    finally:
        release_results()  # the results folder a driver held (repro.core.io.open_results)
