"""Every Python example of the README and of the docs pages runs, as a user would paste it, in a
fresh folder; the README stays one screenful of what a newcomer needs, and its table of commands
is the CLI's."""

from __future__ import annotations

import re

import pytest

from repro.cli import ALIASES, COMMANDS
from tests.conftest import ROOT

PAGES = ("README.md", "docs/python.md", "docs/training.md")
"""The pages with Python examples, in the order their examples are numbered."""
EXAMPLES = [(page, code) for page in PAGES
            for code in re.findall(r"```python\n(.*?)```", (ROOT / page).read_text(), re.S)]
README = (ROOT / "README.md").read_text()


def test_the_pages_have_examples():
    assert len(EXAMPLES) >= 3


@pytest.mark.parametrize("page, code", EXAMPLES,
                         ids=[f"example{i}" for i in range(len(EXAMPLES))])
def test_readme_example_runs(page, code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("REPRO_QUIET", "1")
    exec(compile(code, page, "exec"), {"__name__": "__readme__"})


def test_the_readme_is_under_10_kb():
    assert len(README.encode()) < 10_000


def test_the_readmes_commands_are_the_clis_with_their_other_names():
    rows = re.findall(r"^\| [^|]* \| `([a-z0-9-]+)` \| ([^|]*) \|", README, re.M)
    assert [command for command, _ in rows] == list(COMMANDS)
    listed = {alias: command for command, others in rows
              for alias in re.findall(r"`([a-z0-9-]+)`", others)}
    assert listed == ALIASES


def test_the_readmes_links_lead_to_files():
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README)
    assert links and all((ROOT / link).exists() for link in links), links
