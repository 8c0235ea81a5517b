"""One definition per setting: a config dataclass's fields give the command line (flags, help,
old spellings), the validation messages and the numba parameter records; ``--config FILE`` reads
settings back from JSON or TOML, a run's config.json included."""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

from repro.cli import ALIASES, COMMANDS, OneLineParser, main
from repro.core.config import (Validated, add_config_arguments, field_docs, field_help, flag,
                               given_fields, numba_record)
from repro.envs.bus import BusConfig
from repro.envs.bus.engine import params_record as bus_record
from repro.envs.toy import ToyConfig
from repro.envs.wildfire import WildfireConfig
from repro.envs.wildfire.engine import params_record as wildfire_record
from repro.learn.config import TrainConfig
from repro.studies.races.race import RaceConfig
from repro.studies.races.scaling import ScalingConfig
from repro.studies.races.wildfire_races import BeyondRacesConfig
from repro.studies.training import train
from repro.studies.wildfire.study import BehaviourConfig

CONFIGS = (WildfireConfig, BusConfig, ToyConfig, TrainConfig, RaceConfig, ScalingConfig,
           BeyondRacesConfig, BehaviourConfig)
"""The configs every field of which is a flag."""


@dataclasses.dataclass(frozen=True)
class Scratch(Validated):
    """A config as a new environment would write it."""

    count: int = 3
    """How many. More words here."""
    rate: float | None = None
    """A rate (1/s); None: none."""
    sizes: tuple[float, ...] = (1.0, 2.0)
    """Sizes (m)."""
    loud: bool = True
    """Whether it is loud."""
    mode: str = "a"
    """A mode, left out of the numba record."""

    ALIASES: ClassVar[dict[str, str]] = {"old_loud": "loud"}
    SCALES: ClassVar[dict[str, dict]] = {"smoke": dict(count=1), "quick": {}, "paper": {}}

    def validate(self) -> None:
        self.check(self.count >= 1, "count", "an integer >= 1")


def parser_of(cls: type) -> OneLineParser:
    parser = OneLineParser(prog="test")
    add_config_arguments(parser, cls)
    return parser


def test_a_new_field_is_a_flag_a_help_text_a_message_and_a_record_entry():
    """A switch is one field: its flag, help, old spelling, check and record entry follow."""
    parser = parser_of(Scratch)
    help_text = parser.format_help()
    for text in ("--count", "How many.", "--rate", "--sizes", "--loud", "--no-loud",
                 "--old-loud", "(default: 3; smoke: 1)", "(default: 1.0 2.0)"):
        assert text in help_text
    assert "More words" not in help_text  # the first sentence only
    args = parser.parse_args(["--rate", "0.5", "--sizes", "4", "5", "--no-old-loud"])
    assert given_fields(args, Scratch) == dict(rate=0.5, sizes=(4.0, 5.0), loud=False)
    assert given_fields(parser.parse_args(["--rate", "none"]), Scratch) == dict(rate=None)
    cfg = Scratch(**given_fields(args, Scratch))
    record = numba_record(cfg, derived=7)[0]
    assert record.dtype.names == ("count", "rate", "sizes", "loud", "derived")
    assert (record["count"], record["rate"], list(record["sizes"]), record["loud"],
            record["derived"]) == (3, 0.5, [4.0, 5.0], False, 7)
    assert numba_record(Scratch())[0]["rate"] == 0.0  # None as 0
    with pytest.raises(Exception, match="--count: must be an integer >= 1, got 0"):
        Scratch(count=0)


@pytest.mark.parametrize("cls", CONFIGS)
def test_every_field_has_a_docstring_and_a_flag_that_shows_it(cls):
    parser = parser_of(cls)
    docs = field_docs(cls)
    for field in dataclasses.fields(cls):
        action = parser._option_string_actions[flag(field.name)]
        assert action.dest == field.name
        first = field_help(cls, field.name)
        assert len(first) > 5 and docs[field.name].split()[0] in first
        assert action.help.replace("%%", "%").startswith(first)  # argparse unescapes %%


@pytest.mark.parametrize("cls", CONFIGS)
def test_aliases_name_fields_and_are_not_fields_themselves(cls):
    fields = {f.name for f in dataclasses.fields(cls)}
    aliases = getattr(cls, "ALIASES", {})
    assert set(aliases.values()) <= fields and not set(aliases) & fields


@pytest.mark.parametrize("cls, old, new", [
    (WildfireConfig, ["--no-quirk-q3"], ["--no-quirk-q3-unclamped-health"]),
    (WildfireConfig, ["--quirk-q1", "--no-quirk-q5"],
     ["--quirk-q1-stale-attack", "--no-quirk-q5-discount-from-action-start"]),
    (BusConfig, ["--no-b1", "--b4"], ["--no-b1-reward", "--b4-round-half-even"]),
    (TrainConfig, ["--obs-norm"], ["--normalize-obs"]),
    (TrainConfig, ["--no-obs-norm"], ["--no-normalize-obs"]),
    (RaceConfig, ["--distribution", "chi2", "--distribution", "gamma"],
     ["--distributions", "chi2", "gamma"]),
    (BeyondRacesConfig, ["--policy", "random"], ["--policies", "random"]),
])
def test_an_old_spelling_sets_the_same_field(cls, old, new):
    given = given_fields(parser_of(cls).parse_args(old), cls)
    assert given and given == given_fields(parser_of(cls).parse_args(new), cls)


@pytest.mark.parametrize("cfg", [WildfireConfig(), WildfireConfig(dt=0.5, max_decisions=None),
                                 WildfireConfig.corrected(n_clusters=4)])
def test_the_wildfire_record_holds_every_setting_the_kernels_read(cfg):
    rec = wildfire_record(cfg, count_races=True)[0]
    for field in dataclasses.fields(cfg):
        value = getattr(cfg, field.name)
        if not isinstance(value, str):
            assert rec[field.name] == (0 if value is None else value), field.name
    assert rec["released_order"] == (cfg.same_instant_order == "released")
    assert rec["t_max"] == cfg.t_max and rec["n_fires"] == cfg.n_fires and rec["count_races"]


def test_the_bus_record_holds_every_setting_the_kernels_read():
    cfg = BusConfig.corrected(headway=5.0)
    rec = bus_record(cfg)[0]
    assert list(rec["arrival_rate"]) == list(cfg.arrival_rate)
    assert list(rec["rate_s"]) == [r / 60.0 for r in cfg.arrival_rate]
    assert rec["headway_s"] == 300.0 and not rec["b5_timing"] and rec["travel_time"] == 180.0


def train_parser(env: str) -> OneLineParser:
    parser = OneLineParser(prog="repro train")
    train.add_arguments(parser)
    train.extend_arguments(parser, ["--env", env])
    return parser


@pytest.mark.parametrize("env, cls", [("toy", ToyConfig), ("wildfire", WildfireConfig),
                                      ("bus", BusConfig)])
def test_train_has_a_flag_for_every_training_and_environment_setting(env, cls):
    options = train_parser(env)._option_string_actions
    for config in (TrainConfig, cls):
        for field in dataclasses.fields(config):
            assert options[flag(field.name)].help, field.name


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_option_of_every_command_has_help(name):
    module = importlib.import_module(COMMANDS[name][0])
    parser = OneLineParser(prog=name)
    module.add_arguments(parser)
    if hasattr(module, "extend_arguments"):
        module.extend_arguments(parser, ["--env", "wildfire"])
    missing = [a.option_strings or a.dest for a in parser._actions if not a.help]
    assert missing == []
    shown = parser.format_help()  # argparse fills in the help texts here (a bare % fails)
    assert all((a.option_strings[0] if a.option_strings else a.metavar or a.dest) in shown
               for a in parser._actions)


def run_cli(argv: list[str], capsys) -> tuple[int, str, str]:
    try:
        code = main(argv)
    except SystemExit as exit_:  # argparse's own errors
        code = exit_.code
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("argv, says", [
    (["train", "--env", "toy", "--epochs", "x"], "argument --epochs: must be an integer, got 'x'"),
    (["train", "--env", "toy", "--epochs", "0"], "--epochs: must be an integer >= 1"),
    (["train", "--env", "toy", "--hidden", "0"], "--hidden: must be one or more positive"),
    (["train", "--env", "toy", "--init", "zeros"], "--init: must be one of xavier, orthogonal"),
    (["train"], "--env: must be given"),
    (["train", "--env", "wildfire", "--max-decisions", "-1"], "--max-decisions: must be"),
    (["train", "--env", "wildfire", "--v-uav", "0"], "--v-uav: must be a number > 0"),
    (["train", "--env", "wildfire", "--no-quirk-q3-unclamped-health=1"], "ignored explicit"),
    (["train", "--env", "bus", "--n-buses", "0"], "--n-buses: must be an integer >= 1"),
    (["train", "--env", "bus", "--alight-fraction", "0.5"], "--alight-fraction: must be 10"),
    (["race", "--exact-n", "1"], "--exact-n: must be one or more integers >= 2"),
    (["scaling", "--split-n", "1"], "--split-n: must be an integer >= 2"),
    (["fig-transfer", "--seeds", "0"], "--seeds: must be an integer >= 1"),
    (["learner-ablation", "--test-episodes", "x"], "argument --test-episodes: must be an integer"),
])
def test_a_bad_flag_is_one_line_and_exit_2_and_writes_nothing(argv, says, tmp_path, monkeypatch,
                                                              capsys):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(argv, capsys)
    assert (code, out, len(err.strip().splitlines())) == (2, "", 1)
    assert says in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name, text, says", [
    ("a.toml", 'env = "toy"\nepochs = 0\n', "a.toml: epochs: must be an integer >= 1, got 0"),
    ("a.toml", 'env = "toy"\nepochs = "x"\n', "a.toml: epochs: must be an integer, got 'x'"),
    ("a.toml", 'env = "toy"\nepochs = 1.5\n', "a.toml: epochs: must be an integer"),
    ("a.toml", 'env = "toy"\nfoo = 1\n', "a.toml: foo: must be a setting of this command: "),
    ("a.toml", 'env = "toy"\nepochs =\n', "--config: must be a readable JSON or TOML file"),
    ("a.json", '{"env": "toy", "hidden": [0]}', "a.json: hidden: must be one or more"),
    ("a.json", '{"env": "toy", "normalize_obs": 1}', "a.json: normalize_obs: must be true or"),
    ("a.json", '{"env": "wildfire", "quirk_q3": "no"}', "a.json: quirk_q3: must be true or"),
    ("a.json", '{"env": "wildfire", "dt": -1}', "a.json: dt: must be a number > 0"),
    ("a.json", '{"env": "wildfire", "same_instant_order": "fifo"}',
     "a.json: same_instant_order: must be released or scheduling"),
    ("a.json", '{"env": "bus", "b1": true, "b1_reward": false}',
     "a.json: b1_reward: must be given once"),
    ("a.json", '[1, 2]', "--config: must be a JSON object or TOML table"),
    ("a.json", '{"train": {"epochs": 1}, "env": {}, "env_name": 3}',
     "--config: must be a run config naming its environment"),
    ("a.json", '{"env": "toy", "config": "b.json"}', "a.json: config: must be a setting"),
])
def test_a_bad_config_file_is_one_line_naming_the_key(name, text, says, tmp_path, monkeypatch,
                                                      capsys):
    monkeypatch.chdir(tmp_path)
    Path(name).write_text(text)
    code, out, err = run_cli(["train", "--config", name], capsys)
    assert (code, out, len(err.strip().splitlines())) == (2, "", 1)
    assert says in err
    assert [p.name for p in tmp_path.iterdir()] == [name]


def test_a_study_takes_a_config_file_and_refuses_a_key_it_has_no_flag_for(tmp_path, monkeypatch,
                                                                         capsys):
    monkeypatch.chdir(tmp_path)
    Path("s.toml").write_text('seeds = 0\nno_quirk = ["q3"]\n')
    code, out, err = run_cli(["fig-transfer", "--scale", "smoke", "--config", "s.toml"], capsys)
    assert (code, out) == (2, "") and "s.toml: seeds: must be an integer >= 1, got 0" in err
    Path("s.toml").write_text('n_boot = 10\n')
    code, out, err = run_cli(["fig-transfer", "--config", "s.toml"], capsys)
    assert code == 2 and "s.toml: n_boot: must be a setting of this command" in err
    assert [p.name for p in tmp_path.iterdir()] == ["s.toml"]


def parsed(argv: list[str]) -> argparse.Namespace:
    """What ``main`` hands a command: the parsed arguments (the command not run)."""
    seen = {}
    module = importlib.import_module(COMMANDS[ALIASES.get(argv[0], argv[0])][0])

    def grab(args):
        seen["args"] = args
        return args

    originals = module.configure, module.run
    module.configure, module.run = grab, lambda *_: 0
    try:
        assert main(argv) == 0
    finally:
        module.configure, module.run = originals
    return seen["args"]


def test_flags_override_the_file_and_old_keys_read_as_new(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('env = "wildfire"\nepochs = 3\nquirk_q3 = false\nobs_norm = true\n'
                    'hidden = [8, 8]\ndt = 0.5\nmax_decisions = "none"\n')
    args = parsed(["train", "--config", str(path), "--epochs", "5", "--quirk-q3-unclamped-health"])
    run = train.configure(args)
    cfg, env_cfg = run.train, run.env_config
    assert (cfg.epochs, cfg.normalize_obs, cfg.hidden) == (5, True, (8, 8))
    assert (env_cfg.quirk_q3_unclamped_health, env_cfg.dt, env_cfg.max_decisions) == (
        True, 0.5, None)
    # sections, as in a run's config.json, and flag spellings as keys
    path.write_text('[train]\nenv = "bus"\n"batch-episodes" = 7\n[env]\nno-b2 = true\n')
    run = train.configure(parsed(["train", "--config", str(path), "--out", str(tmp_path / "r")]))
    cfg, env_cfg = run.train, run.env_config
    assert (cfg.env, cfg.batch_episodes, env_cfg.b2_headway, env_cfg.b1_reward) == (
        "bus", 7, False, True)


def train_run(argv: list[str], capsys) -> None:
    code, _, err = run_cli(["train", *argv], capsys)
    assert code == 0, err


def rows(folder: Path) -> list[list[str]]:
    """progress.csv without its timing columns."""
    lines = (folder / "progress.csv").read_text().splitlines()
    keep = [i for i, c in enumerate(lines[0].split(",")) if not c.startswith("seconds")]
    return [[line.split(",")[i] for i in keep] for line in lines]


@pytest.mark.parametrize("argv", [
    ["--env", "toy", "--scale", "smoke", "--epochs", "1"],
    ["--env", "wildfire", "--scale", "smoke", "--epochs", "1", "--dt", "0.5",
     "--max-decisions", "0", "--no-quirk-q3", "--hidden", "8", "--batch-decisions", "60",
     "--learner", "suite"],
    ["--env", "bus", "--scale", "smoke", "--epochs", "1", "--corrected", "--b2",
     "--batch-episodes", "2"],
])
def test_a_runs_config_json_fed_back_gives_the_same_config(argv, tmp_path, capsys):
    train_run([*argv, "--out", str(tmp_path / "a")], capsys)
    saved = tmp_path / "a" / "config.json"
    # another scale and learner: the file's settings override both
    train_run(["--config", str(saved), "--scale", "paper", "--out", str(tmp_path / "b")], capsys)
    assert (tmp_path / "b" / "config.json").read_bytes() == saved.read_bytes()
    assert rows(tmp_path / "b") == rows(tmp_path / "a")


def test_an_old_run_folder_resumes_from_its_config_json(tmp_path, capsys):
    """A run folder whose config.json predates settings (and spells switches the old way) is
    resumed by ``train --config`` of that file, as by its original command line."""
    argv = ["--env", "toy", "--scale", "smoke", "--learner", "suite", "--batch-episodes", "4"]
    train_run([*argv, "--epochs", "2", "--out", str(tmp_path / "whole")], capsys)
    old = tmp_path / "old"
    train_run([*argv, "--epochs", "1", "--out", str(old)], capsys)
    config = json.loads((old / "config.json").read_text())
    # as written before these settings existed: they held the value BEFORE_ADDED names
    for key, value in TrainConfig.BEFORE_ADDED.items():
        assert config["train"].pop(key) == value
    config["train"]["obs_norm"] = config["train"].pop("normalize_obs")
    (old / "config.json").write_text(json.dumps(config))
    train_run(["--config", str(old / "config.json"), "--epochs", "2", "--out", str(old)], capsys)
    assert rows(old) == rows(tmp_path / "whole")
    resumed = json.loads((old / "config.json").read_text())
    assert resumed == json.loads((tmp_path / "whole" / "config.json").read_text())


def test_the_numba_record_of_a_config_is_its_fields_and_nothing_hand_listed():
    """A field added to a config reaches the kernels: the record is made from the fields."""
    @dataclasses.dataclass(frozen=True)
    class Grown(WildfireConfig):
        new_switch: bool = False
        """A switch added in one place."""

    rec = wildfire_record(Grown(new_switch=True))[0]
    assert rec["new_switch"] and rec["decision_latency"] == WildfireConfig.decision_latency
    args = parser_of(Grown).parse_args(["--new-switch"])
    assert given_fields(args, Grown) == dict(new_switch=True)
    assert np.isclose(rec["t_max"], Grown().t_max)


@pytest.mark.parametrize("argv", [
    ["--no-quirk-q3-unclamped-health", "--no-quirk-q5-discount-from-action-start"],
    ["--no-quirk-q5", "--no-quirk-q3"],
    ["--no-quirk", "q3", "--no-quirk", "Q5"],
    ["--no-quirk-q3-unclamped-health", "--no-quirk", "q5", "--quirk-q1-stale-attack"],
])
def test_a_study_spells_a_quirk_as_train_does_and_takes_the_old_spellings(argv, tmp_path):
    """fig-transfer switches a quirk off by train's flag; the old ones give the same study."""
    from repro.studies.transfer.transfer import configure

    cfg = configure(parsed(["fig-transfer", "--scale", "smoke", *argv])).study
    assert cfg.quirks_off == ("q3", "q5") and cfg.name == "transfer_no_q3_no_q5"
    sim = cfg.test_simulator()
    assert not (sim.quirk_q3_unclamped_health or sim.quirk_q5_discount_from_action_start)
    assert sim.quirk_q1_stale_attack and sim.quirk_q4_latency_not_interrupted
