"""The claims registry: one small check per claim C1..C11 of SPEC section 1, rendered to
``paper_claims.md`` by ``python -m repro claims`` (``make claims``).

A check reads result files and returns a :class:`Verdict`. A claim whose result files do not exist,
or lack the rows and columns its check reads (a stale or hand-edited file), reads "not yet run",
never PASS. Each experiment module contributes its claims in
``repro/claims/<topic>.py`` as a list ``CLAIMS``.
"""

from __future__ import annotations

import argparse
import importlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from repro.core.errors import require
from repro.core.io import check_writable_dir, sidecar_path, write_text

NOT_RUN = "not yet run"
VERDICTS = ("PASS", "FAIL", "PARTIAL", NOT_RUN)
TOPICS = ("repro.claims.race", "repro.claims.scaling", "repro.claims.bus",
          "repro.claims.wildfire")


@dataclass(frozen=True)
class Verdict:
    ours: str
    """Our value, formatted for the table."""
    verdict: str
    """One of VERDICTS."""
    detail: str = ""
    """How the verdict was reached (tolerance, intervals, caveats)."""
    scale: str = ""
    """Scale of the run the value comes from (read from the provenance sidecar)."""


@dataclass(frozen=True)
class Claim:
    id: str
    text: str
    paper: str
    """The paper's value or statement."""
    tolerance: str
    """What counts as reproduced."""
    command: str
    """The command that regenerates the result files the check reads."""
    check: Callable[[Path], Verdict] | None = None
    """None until the experiment that checks the claim exists."""

    def evaluate(self, results: Path) -> Verdict:
        if self.check is None:
            return Verdict("-", NOT_RUN, "no driver for this claim yet")
        try:
            v = self.check(results)
        except FileNotFoundError as err:
            return Verdict("-", NOT_RUN,
                           f"missing {Path(err.filename).name if err.filename else err}")
        # a file without the rows or columns the check reads; pandas' EmptyDataError is a ValueError
        except (KeyError, AttributeError, IndexError, ValueError) as err:
            return Verdict("-", NOT_RUN, f"results incomplete ({type(err).__name__}: {err}); "
                           f"rerun `{self.command}`")
        require(v.verdict in VERDICTS, "verdict", "one of " + ", ".join(VERDICTS), v.verdict)
        return v


def scale_of(result: Path) -> str:
    """The scale recorded in a result's provenance sidecar ('unknown' without one)."""
    side = sidecar_path(result)
    return json.loads(side.read_text()).get("scale", "unknown") if side.exists() else "unknown"


def registry() -> list[Claim]:
    claims: list[Claim] = []
    for mod in TOPICS:
        claims.extend(importlib.import_module(mod).CLAIMS)
    return sorted(claims, key=lambda c: int(c.id[1:]))


def _cell(s: str) -> str:
    return s.replace("|", "\\|").replace("\n", " ")


def render(results: Path) -> str:
    rows = [(c, c.evaluate(results)) for c in registry()]
    lines = [
        "# Paper claims: the paper's numbers beside ours",
        "",
        f"Rendered by `make claims` (`python -m repro claims`) from the CSVs under `{results}/`;",
        "do not edit by hand. A claim whose results are missing reads \"not yet run\". The scale",
        "column says which scale (SPEC section 6: smoke, quick, paper) produced the numbers.",
        "",
        "| id | claim | paper | ours | tolerance | verdict | scale | regenerate |",
        "|----|-------|-------|------|-----------|---------|-------|------------|",
    ]
    for c, v in rows:
        lines.append("| " + " | ".join(_cell(x) for x in (
            c.id, c.text, c.paper, v.ours, c.tolerance, f"**{v.verdict}**", v.scale or "-",
            f"`{c.command}`")) + " |")
    lines += ["", "## Details", ""]
    for c, v in rows:
        lines.append(f"- **{c.id}** ({v.verdict}): {v.detail or '-'}")
    # a topic's NOTES: text, or a function of the results folder that returns it
    notes = [getattr(importlib.import_module(m), "NOTES", "") for m in TOPICS]
    notes = [n(results) if callable(n) else n for n in notes]
    for note in filter(None, notes):
        lines += ["", note.strip()]
    return "\n".join(lines) + "\n"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--results-dir", default="results", help="folder the checks read")
    p.add_argument("--out", default="paper_claims.md", help="the rendered table")


def run(args: argparse.Namespace) -> int:
    results, out = Path(args.results_dir), Path(args.out)
    # a mistyped folder would otherwise render a table of "not yet run"
    require(results.is_dir(), "--results-dir", "an existing folder of result files", str(results))
    require(not out.is_dir(), "--out", "a file, not a folder", str(out))
    check_writable_dir(out.parent, "--out")
    text = render(results)
    write_text(out, text)
    print(f"wrote {out}")
    return 0
