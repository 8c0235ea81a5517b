"""The code says what it does and why in the present tense: no issue numbers in `repro/` (the
history lives in CHANGELOG.md)."""

from __future__ import annotations

import re

from tests.conftest import ROOT

ISSUE = re.compile(r"\bissues? [0-9]+", re.IGNORECASE)


def test_no_issue_numbers_in_the_package():
    found = [f"{path.relative_to(ROOT)}:{n}: {line.strip()}"
             for path in sorted((ROOT / "repro").rglob("*.py"))
             for n, line in enumerate(path.read_text().splitlines(), 1) if ISSUE.search(line)]
    assert found == []


def test_the_check_sees_an_issue_number():
    assert ISSUE.search("the default since Issue 23") and not ISSUE.search("numba issue #4807")
