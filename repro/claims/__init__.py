"""The claims registry: one small check per claim C1..C11 of docs/semantics.md section 1.2, rendered
to ``paper_claims.md`` by ``python -m repro claims`` (``make claims``), and the questions beyond the
paper, X1.., in a section of their own.

Only paper-scale results make ``paper_claims.md``. The verdicts of a smaller scale's results
(``claims --results-dir results/quick``, the end of ``make reproduce SCALE=quick``) go to
``results/<scale>/claims.md``, marked as a smoke check: they show that every driver ran and every
check reads its files, and are no evidence for or against a claim (:data:`SMOKE_NOTE`).

A check reads result files and returns a :class:`Verdict`. A claim whose result files do not exist,
or lack the rows and columns its check reads (a stale or hand-edited file), reads "not yet run",
never PASS; any other error a check raises is a bug in it and propagates
(:func:`is_incomplete`). Each experiment module contributes its claims in
``repro/claims/<topic>.py`` as a list ``CLAIMS``.
"""

from __future__ import annotations

import argparse
import importlib
import json
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from repro.core.errors import require
from repro.core.io import check_names, check_writable_dir, read_provenance, write_text

NOT_RUN = "not yet run"
AMBIGUOUS = "AMBIGUOUS"
VERDICTS = ("PASS", "PARTIAL", "FAIL", AMBIGUOUS, NOT_RUN)
LEGEND = {
    "PASS": "reproduces within the stated tolerance",
    "PARTIAL": "part of the claim reproduces (the detail says which part)",
    "FAIL": "does not reproduce",
    AMBIGUOUS: "the paper's definition admits readings with different verdicts (the detail gives "
               "each)",
    NOT_RUN: "its result files are missing or incomplete",
}
"""What each verdict means."""
TOPICS = ("repro.claims.race", "repro.claims.scaling", "repro.claims.bus",
          "repro.claims.wildfire", "repro.claims.learner", "repro.claims.beyond",
          "repro.claims.beyond_races", "repro.claims.beyond_sb3")
BEYOND = "X"
"""Id prefix of the claims beyond the paper: questions the paper raises and leaves open.
They are rendered in a section of their own, and a scale's results are complete without them (so
that `make claims` keeps reading the paper scale until they are run there)."""


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
    outdated: bool = False
    """The result files exist but were made on semantics the engines no longer follow (the verdict
    is then "not yet run"); a rerun is pending."""


@dataclass(frozen=True)
class Claim:
    id: str
    text: str
    paper: str
    """The paper's value or statement (beyond the paper: the hypothesis the check tests)."""
    tolerance: str
    """What counts as reproduced."""
    command: str
    """The command that regenerates the result files the check reads."""
    check: Callable[[Path], Verdict] | None = None
    """None until the experiment that checks the claim exists."""
    where: str = ""
    """Where the paper makes the claim (figure, table or section number)."""

    def evaluate(self, results: Path) -> Verdict:
        if self.check is None:
            return Verdict("-", NOT_RUN, "no driver for this claim yet")
        try:
            v = self.check(results)
        except FileNotFoundError as err:
            return Verdict("-", NOT_RUN,
                           f"missing {Path(err.filename).name if err.filename else err}")
        except Exception as err:
            if not is_incomplete(err):
                raise  # a bug in the check, which must not pass for missing data
            return Verdict("-", NOT_RUN, f"results incomplete ({type(err).__name__}: {err}); "
                           f"rerun `{self.command}`")
        require(v.verdict in VERDICTS, "verdict", "one of " + ", ".join(VERDICTS), v.verdict)
        return v


class IncompleteResult(LookupError):
    """A result file lacks rows or values a check reads, found by the check itself (a policy
    without rows, say): the claim reads "not yet run"."""


_TABLE_ERRORS = (KeyError, IndexError, ValueError, AttributeError)
_TABLE_MODULES = ("pandas", "numpy")


def is_incomplete(err: BaseException) -> bool:
    """Whether ``err`` says that a result file lacks what a check reads: an
    :class:`IncompleteResult`, or a lookup that failed inside pandas or numpy (a missing column,
    row or attribute of a table, an empty file: pandas' EmptyDataError is a ValueError). The same
    errors raised by a check's own code are bugs in it, not missing data."""
    if isinstance(err, IncompleteResult):
        return True
    if not isinstance(err, _TABLE_ERRORS) or err.__traceback__ is None:
        return False
    tb = err.__traceback__
    while tb.tb_next is not None:
        tb = tb.tb_next
    return str(tb.tb_frame.f_globals.get("__name__", "")).split(".")[0] in _TABLE_MODULES


def scale_of(result: Path) -> str:
    """The scale recorded in a result's provenance sidecar. A result without its sidecar (its write
    was interrupted) counts as missing: FileNotFoundError, which reads "not yet run"."""
    return read_provenance(result).get("scale", "unknown")


def at_most_partial(verdict: str, n_min: int) -> tuple[str, str]:
    """With one policy (or run) per cell, ``n_min`` = 1, the CIs are points: no interval, so no
    PASS. Returns the verdict and the caveat to append to the detail."""
    if n_min >= 2:
        return verdict, ""
    return ("PARTIAL" if verdict == "PASS" else verdict,
            " One policy per simulator: the intervals are points, so at most PARTIAL.")


@dataclass(frozen=True)
class Reading:
    """One set-up a claim is checked on: a learner (and simulator version), whose result files
    carry ``suffix`` after their stem."""

    label: str
    suffix: str


LEARNER_READINGS = (Reading("authors' learner", ""), Reading("suite's learner", "_suite"))
"""The two named learners' results (``learner_stem``), the authors' deciding."""


def side_by_side(check: Callable[[Path, str], Verdict],
                 readings: tuple[Reading, ...]) -> Callable[[Path], Verdict]:
    """A check decided on the first reading, the others beside it: the table shows each one's
    value, the detail each one's verdict and detail. A reading whose files are missing says
    "not yet run"; when it is the deciding one, so does the claim."""
    def checked(results: Path) -> Verdict:
        seen: list[tuple[Reading, Verdict | None, str]] = []
        for reading in readings:
            try:
                seen.append((reading, check(results, reading.suffix), ""))
            except FileNotFoundError as err:
                seen.append((reading, None, Path(err.filename or str(err)).name))
        first = seen[0][1]
        ours = "; ".join(f"{r.label}: {v.ours if v else NOT_RUN}" + (
            f" ({v.verdict})" if v and i else "") for i, (r, v, _) in enumerate(seen))
        parts = [f"**{r.label}**" + (f" ({v.scale} scale): {v.verdict}. {v.detail}" if v
                                     else f": {NOT_RUN} (missing {missing}).")
                 for r, v, missing in seen]
        detail = "Decided on the first set-up. " + " ".join(parts)
        if first is None:
            return Verdict(ours, NOT_RUN, detail)
        return Verdict(ours, first.verdict, detail, first.scale, first.outdated)
    return checked


def learner_of(result: Path) -> str:
    """The named learner of a result's runs, as its sidecar records it (beside the config, or in it
    at any depth of a study made of studies; the outermost first); results made before the
    learner was a setting were the suite's."""
    def find(config: object) -> str | None:
        if not isinstance(config, dict):
            return None
        if isinstance(config.get("learner"), str):
            return config["learner"]
        return next(filter(None, map(find, config.values())), None)
    return find(read_provenance(result)) or "suite"


def registry() -> list[Claim]:
    claims: list[Claim] = []
    for mod in TOPICS:
        claims.extend(importlib.import_module(mod).CLAIMS)
    return sorted(claims, key=lambda c: (is_beyond(c), int(c.id[1:])))


def is_beyond(claim: Claim) -> bool:
    """Whether ``claim`` is a question beyond the paper (X1..) rather than one of its claims."""
    return claim.id.startswith(BEYOND)


def _cell(s: str) -> str:
    return s.replace("|", "\\|").replace("\n", " ")


PAPER = "paper"
"""The scale whose results, and only whose, make paper_claims.md."""
PAPER_CLAIMS = "paper_claims.md"
SMOKE_OUT = "claims.md"
"""The file a smaller scale's verdicts go to, in its results folder."""
SMOKE_NOTE = (
    "**A smoke check, not evidence.** These verdicts come from results of the {scale} scale: a "
    "few seeds, short training and few test episodes, so intervals are wide or points and "
    "trained policies are far from what the paper's budgets give. They show that every driver "
    "ran and that each claim's check reads its files; a verdict here may differ from the "
    "paper-scale one either way. The evidence is paper_claims.md, rendered from `results/paper/`.")


def result_scales(results: Path) -> set[str]:
    """The scales recorded by the provenance sidecars of the result files directly in
    ``results``."""
    return {str(json.loads(side.read_text()).get("scale", "unknown"))
            for side in results.glob("*.provenance.json")}


def is_paper_scale(results: Path) -> bool:
    """Whether every result file directly in ``results`` is of the paper scale (and there is
    one)."""
    return result_scales(results) == {PAPER}


def render(results: Path) -> str:
    """paper_claims.md (paper-scale results), or a smaller scale's smoke check: a tally, one short
    row per claim, then each claim's detail."""
    evaluated = [(c, c.evaluate(results)) for c in registry()]
    rows = [(c, v) for c, v in evaluated if not is_beyond(c)]
    beyond = [(c, v) for c, v in evaluated if is_beyond(c)]
    paper = is_paper_scale(results)
    scale = " and ".join(sorted(result_scales(results))) or "no"
    title = ("# Paper claims: the paper's numbers beside ours" if paper else
             f"# Smoke check ({scale} scale): the paper's numbers beside a short run's")
    source = ("from the paper-scale result CSVs only (a smaller scale's verdicts are a smoke "
              f"check, `results/<scale>/{SMOKE_OUT}`)" if paper else
              f"from the result CSVs in `{results}/`")
    lines = [
        title,
        "",
        f"**{len(rows)} claims: {_tally(rows)}** (results in `{results}/`, {_scales(rows)} scale).",
        "",
        *([] if paper else [*textwrap.wrap(SMOKE_NOTE.format(scale=scale), WIDTH), ""]),
        f"Rendered by `make claims` (`python -m repro claims`) {source}; do not edit by hand. "
        "The verdicts:",
        "",
        *(f"- **{k}**: {m}." for k, m in LEGEND.items()),
        "",
        "| id | claim | paper | ours | verdict |",
        "|----|-------|-------|------|---------|",
    ]
    lines += [*_table(rows), "", "## Details", *_details(rows)]
    # a topic's NOTES: text, or a function of the results folder that returns it
    notes = [getattr(importlib.import_module(m), "NOTES", "") for m in TOPICS]
    notes = [n(results) if callable(n) else n for n in notes]
    for note in filter(None, notes):
        lines += ["", note.strip()]
    if beyond:
        intro = ("Questions the paper raises and leaves open, answered with the same "
                 "machinery; a verdict says whether the hypothesis holds. "
                 f"**{len(beyond)} questions: {_tally(beyond)}** ({_scales(beyond)} scale).")
        lines += ["", "## Beyond the paper", "", *textwrap.wrap(intro, WIDTH),
                  "", "| id | question | hypothesis | ours | verdict |",
                  "|----|----------|------------|------|---------|",
                  *_table(beyond), *_details(beyond)]
    return "\n".join(lines) + "\n"


def _tally(rows: list[tuple[Claim, Verdict]]) -> str:
    counts = {k: sum(v.verdict == k for _, v in rows) for k in VERDICTS}
    return ", ".join(f"{n} {k}" for k, n in counts.items() if n)


def _scales(rows: list[tuple[Claim, Verdict]]) -> str:
    return " and ".join(sorted({v.scale for _, v in rows if v.scale})) or "no"


def _table(rows: list[tuple[Claim, Verdict]]) -> list[str]:
    lines = []
    for c, v in rows:
        where = f" ({c.where})" if c.where else ""
        lines.append("| " + " | ".join(_cell(x) for x in (
            c.id, c.text, c.paper + where, v.ours, f"**{v.verdict}**")) + " |")
    return lines


def _details(rows: list[tuple[Claim, Verdict]]) -> list[str]:
    lines = []
    for c, v in rows:
        lines += ["", f"### {c.id}: {v.verdict}" + (f" ({v.scale} scale)" if v.scale else ""), ""]
        lines += textwrap.wrap(f"Tolerance: {c.tolerance}. {v.detail or ''}", WIDTH,
                               break_on_hyphens=False)
        lines.append(f"Regenerate: `{c.command}`.")
    return lines


WIDTH = 100
"""Line width of the details."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--results-dir", default="results/paper",
                   help="folder the checks read (default results/paper)")
    p.add_argument("--out", help=f"the rendered table (default {PAPER_CLAIMS} for paper-scale "
                   f"results; for those of a smaller scale, a smoke check, "
                   f"<results-dir>/{SMOKE_OUT}, never {PAPER_CLAIMS})")


def run(args: argparse.Namespace) -> int:
    require(args.results_dir.strip() != "", "--results-dir",
            "a folder of result files (not an empty path)", args.results_dir)
    results = Path(args.results_dir)
    # a mistyped or empty folder would otherwise render a table of "not yet run" over the claims
    require(results.is_dir() and any(results.glob("*.provenance.json")), "--results-dir",
            "an existing folder of result files (CSVs with their provenance sidecars)",
            str(results))
    paper = is_paper_scale(results)
    default = PAPER_CLAIMS if paper else str(results / SMOKE_OUT)
    require(args.out is None or args.out.strip() != "", "--out", "a file name", args.out)
    out = check_names(default if args.out is None else args.out, "--out")
    require(paper or out.name != PAPER_CLAIMS, "--out", f"another file than {PAPER_CLAIMS} for "
            f"results of the {' and '.join(sorted(result_scales(results)))} scale "
            f"({PAPER_CLAIMS} is rendered from paper-scale results only)", str(out))
    require(not out.is_dir(), "--out", "a file, not a folder", str(out))
    check_writable_dir(out.parent, "--out")
    text = render(results)
    write_text(out, text)
    if not paper:  # the smoke check's table, for the end of `make reproduce`
        print(text.split("\n## Details")[0].rstrip())
    print(f"wrote {out}")
    return 0
