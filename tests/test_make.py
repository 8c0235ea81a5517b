"""One vocabulary: each `python -m repro` command has the Make target of its name, which runs that
command, and every target a user may run is listed by `make help`."""

from __future__ import annotations

import re
import shutil
import subprocess

import pytest

from repro.cli import ALIASES, COMMANDS
from tests.conftest import ROOT

MAKEFILE = (ROOT / "Makefile").read_text()


def recipes() -> dict[str, str]:
    """Target -> its recipe lines (one string) and its prerequisites' line, from the Makefile."""
    found: dict[str, str] = {}
    target = None
    for line in MAKEFILE.splitlines():
        m = re.match(r"^([a-z0-9-]+):(.*)$", line)
        if m:
            target = m.group(1)
            found[target] = m.group(2)
        elif target and line.startswith("\t"):
            found[target] += "\n" + line
        elif not line.strip():
            target = None
    return found


def make_help() -> str:
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    return subprocess.run(["make", "-s", "help"], cwd=ROOT, capture_output=True, text=True,
                          check=True).stdout


@pytest.mark.parametrize("command", COMMANDS)
def test_each_command_has_the_target_of_its_name(command):
    recipe = recipes().get(command)
    assert recipe is not None, f"no Make target {command}"
    assert re.search(rf"\$\(REPRO\) {command}( |$)", recipe), recipe


def test_make_help_lists_every_command_and_alias():
    listed = dict(line.split("\t", 1) for line in make_help().splitlines() if "\t" in line)
    missing = [c for c in [*COMMANDS, *ALIASES] if c not in listed]
    assert not missing
    for alias, command in ALIASES.items():
        assert listed[alias] == f"alias of {command}", (alias, listed[alias])


def test_the_aliases_of_the_makefile_are_those_of_the_cli():
    """An alias is a target without a recipe of its own whose one prerequisite is its command: the
    Makefile has one for each of the CLI's aliases, and no other."""
    aliases = {t: deps.split("##")[0].split()[0] for t, deps in recipes().items()
               if "\n" not in deps and deps.split() and deps.split()[0] in COMMANDS}
    assert aliases == ALIASES


@pytest.mark.parametrize("command", COMMANDS)
def test_every_option_says_what_it_takes(command):
    """Each option has a help text of its own, not a pointer to the source."""
    import importlib

    from repro.cli import OneLineParser

    module = importlib.import_module(COMMANDS[command][0])
    vague = []
    for env in ("bus", "wildfire"):
        parser = OneLineParser(prog=command)
        module.add_arguments(parser)
        if hasattr(module, "extend_arguments"):
            module.extend_arguments(parser, ["--env", env])
        vague += [a.option_strings for a in parser._actions if a.dest != "help" and (
            not a.help or "docstring" in a.help or "see the source" in a.help)]
    assert vague == []
