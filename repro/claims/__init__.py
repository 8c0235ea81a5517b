"""The claims registry: one small check per claim C1..C11 of docs/semantics.md section 1.2, rendered
to ``paper_claims.md`` by ``python -m repro claims`` (``make claims``), and the questions beyond the
paper, X1.., in a section of their own.

Only a complete set of paper-scale results makes ``paper_claims.md``: every result file in the
folder of the paper scale (its sidecar says so, and a run records the paper scale only with the
paper scale's settings: :func:`repro.runs.provenance.run_scale`), and every claim of the paper
read from its files (none "not yet run" for want of them). The verdicts of a smaller scale's results
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
import dataclasses
import importlib
import json
import textwrap
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import numpy as np
import pandas as pd

from repro.core.errors import require
from repro.runs.files import check_names, check_writable_dir, write_text
from repro.runs.results import read_provenance, read_result
from repro.runs.stats import interval, t_limits

INTERVALS = ("t", "percentile")
"""The intervals a claim that compares intervals is decided with (``claims --interval``, default
the first), each claim's verdict under the other rendered beside it:

- ``t``: Student's t interval of a mean (of an IQM, the trimmed-mean t of Tukey and McLaughlin; of
  a difference of means, Welch's), computed here from the result files' per-seed scores or their
  standard errors. The interval-coverage study (``interval_coverage.csv``) measures its coverage at
  3, 5 and 10 runs.
- ``percentile``: the percentile bootstrap CIs the drivers store, which cover less than 95% with 5
  runs (the same study)."""
_INTERVAL: ContextVar[str] = ContextVar("interval", default=INTERVALS[0])


def interval_kind() -> str:
    """The interval the claims are being decided with (:data:`INTERVALS`)."""
    return _INTERVAL.get()


@contextmanager
def intervals_of(kind: str) -> Iterator[None]:
    """Decide the claims checked inside with the intervals ``kind`` (:data:`INTERVALS`)."""
    token = _INTERVAL.set(kind)
    try:
        yield
    finally:
        _INTERVAL.reset(token)


def with_intervals(summary: pd.DataFrame, runs: str = "n_policies") -> pd.DataFrame:
    """A driver's summary (rows with ``mean``, ``sem``, ``ci_low``, ``ci_high`` and the number of
    runs in column ``runs``) with the CIs of :func:`interval_kind`: the t interval from the mean
    and its standard error, or the stored percentile bootstrap."""
    if interval_kind() == "percentile":
        return summary
    lo, hi = t_limits(summary["mean"].to_numpy(), summary["sem"].to_numpy(),
                      summary[runs].to_numpy() - 1)
    return summary.assign(ci_low=lo, ci_high=hi)


def with_difference_intervals(effect: pd.DataFrame, per_policy_path: Path, by: list[str],
                              pair: tuple[str, str], score: str = "adr_ed") -> pd.DataFrame:
    """A driver's table of differences (one row per group of the ``by`` columns: ``difference``,
    the mean ``score`` of simulator ``pair[0]`` minus that of ``pair[1]``, ``ci_low``,
    ``ci_high``, ``degrades``: the CI below 0) with the CIs of :func:`interval_kind`: Welch's t from
    the scores of the per-policy table at ``per_policy_path``, or the stored percentile
    bootstrap."""
    if interval_kind() == "percentile":
        return effect
    per_policy = read_result(per_policy_path)
    limits = []
    for key in zip(*(effect[c] for c in by)):
        g = per_policy[np.logical_and.reduce([per_policy[c] == v for c, v in zip(by, key)])]
        groups = [g[g.simulator == label][score].to_numpy() for label in pair]
        if min(map(len, groups)) == 0:
            raise IncompleteResult(f"no {pair} policies for {dict(zip(by, key))}")
        limits.append(interval(groups, "difference", "t")[1:])
    lo, hi = (np.array(x) for x in zip(*limits))
    return effect.assign(ci_low=lo, ci_high=hi, degrades=hi < 0)


def interval_name() -> str:
    """How a detail names the CIs of :func:`interval_kind`."""
    return "t" if interval_kind() == "t" else "percentile bootstrap"


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
    """The result files exist but were made on semantics the engines no longer follow, or on
    another set-up than the one that decides the claim (the verdict is then "not yet run"); a
    rerun is pending."""
    other: str = ""
    """For a claim that compares intervals: its verdict under the other interval of
    :data:`INTERVALS`, named ("percentile: PASS"; set by :func:`evaluate_with`)."""
    other_ours: str = ""
    """Its value under the other interval, where that differs from ``ours``."""


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
    intervals: bool = False
    """The check compares intervals, those of :func:`interval_kind`: rendered with its verdict
    under the other interval too."""

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


def decided_on(check: Callable[[Path], Verdict], setup: str,
               beside: Callable[[Path], Verdict]) -> Callable[[Path], Verdict]:
    """A claim decided by ``check`` on the set-up that drew the paper's figure (``setup``, as the
    detail names it), the other readings (``beside``) shown after it; "not yet run" while that
    set-up's results are missing or lack what the check reads (a rerun pending, as ``outdated``
    says, where the other readings have their results)."""
    def checked(results: Path) -> Verdict:
        other = beside(results)
        try:
            v = check(results)
        except (FileNotFoundError, IncompleteResult):
            return Verdict(f"{setup}: {NOT_RUN}; {other.ours}", NOT_RUN,
                           f"Decided on {setup}: {NOT_RUN}. Beside it: {other.detail}",
                           other.scale, outdated=other.verdict != NOT_RUN)
        return Verdict(f"{v.ours}; {other.ours}", v.verdict,
                       f"Decided on {setup}. {v.detail} Beside it: {other.detail}", v.scale)
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
DEFAULT_RESULTS = "results/paper"
"""The committed paper-scale results, the only ones whose verdicts go to the checkout's
paper_claims.md; a complete set elsewhere gets a paper_claims.md of its own, in its folder."""
SMOKE_OUT = "claims.md"
"""The file a smaller scale's verdicts go to, in its results folder."""
SMOKE_NOTE = (
    "**A smoke check, not evidence.** These verdicts come from results of the {scale} scale: a "
    "few seeds, short training and few test episodes, so intervals are wide or points and "
    "trained policies are far from what the paper's budgets give. They show that every driver "
    "ran and that each claim's check reads its files; a verdict here may differ from the "
    "paper-scale one either way. The evidence is paper_claims.md, rendered from `results/paper/`.")
INCOMPLETE_NOTE = (
    "**Not the evidence.** These results are of the paper scale, but not all of them: {missing} "
    "lack their result files. paper_claims.md is rendered only from a complete set, "
    "`results/paper/`.")


def result_scales(results: Path) -> set[str]:
    """The scales recorded by the provenance sidecars of the result files directly in
    ``results``."""
    return {str(json.loads(side.read_text()).get("scale", "unknown"))
            for side in results.glob("*.provenance.json")}


def is_paper_scale(results: Path) -> bool:
    """Whether every result file directly in ``results`` is of the paper scale (and there is
    one)."""
    return result_scales(results) == {PAPER}


def evaluate_with(claim: Claim, results: Path, interval: str) -> Verdict:
    """``claim``'s verdict with the intervals ``interval`` (:data:`INTERVALS`); for a claim that
    compares intervals, the other interval's verdict and value in its ``other``."""
    with intervals_of(interval):
        v = claim.evaluate(results)
    if not claim.intervals:
        return v
    other = next(k for k in INTERVALS if k != interval)
    w = evaluate_with(dataclasses.replace(claim, intervals=False), results, other)
    return dataclasses.replace(v, other=f"{other}: {w.verdict}",
                               other_ours="" if w.ours == v.ours else w.ours)


def missing_claims(evaluated: list[tuple[Claim, Verdict]]) -> list[str]:
    """The claims of the paper (not the questions beyond it) that read "not yet run" for want of
    result files or rows; one whose files were made on semantics since changed (``outdated``)
    has its results, and says so."""
    return [c.id for c, v in evaluated if not is_beyond(c) and v.verdict == NOT_RUN
            and not v.outdated]


def evaluate_all(results: Path, interval: str = INTERVALS[0]) -> list[tuple[Claim, Verdict]]:
    """Every claim and question with its verdict on the results in ``results``, claims that
    compare intervals decided with ``interval``'s."""
    return [(c, evaluate_with(c, results, interval)) for c in registry()]


def is_paper_set(results: Path, evaluated: list[tuple[Claim, Verdict]]) -> bool:
    """Whether ``results`` is a complete set of paper-scale results, the only one that makes
    paper_claims.md: every result file of the paper scale, and no claim without its files."""
    return is_paper_scale(results) and not missing_claims(evaluated)


def render(results: Path, interval: str = INTERVALS[0],
           evaluated: list[tuple[Claim, Verdict]] | None = None) -> str:
    """paper_claims.md (a complete set of paper-scale results), or else a smoke check: a tally,
    one short row per claim, then each claim's detail; claims that compare intervals are decided
    with ``interval``'s, the other's verdict beside. ``evaluated``: :func:`evaluate_all`'s, if
    done already."""
    evaluated = evaluate_all(results, interval) if evaluated is None else evaluated
    with intervals_of(interval):
        return _render(results, interval, evaluated)


def _render(results: Path, interval: str, evaluated: list[tuple[Claim, Verdict]]) -> str:
    rows = [(c, v) for c, v in evaluated if not is_beyond(c)]
    beyond = [(c, v) for c, v in evaluated if is_beyond(c)]
    paper = is_paper_set(results, evaluated)
    scale = " and ".join(sorted(result_scales(results))) or "no"
    note = (SMOKE_NOTE.format(scale=scale) if not is_paper_scale(results) else
            INCOMPLETE_NOTE.format(missing=", ".join(missing_claims(evaluated))))
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
        *([] if paper else [*textwrap.wrap(note, WIDTH), ""]),
        f"Rendered by `make claims` (`python -m repro claims`) {source}; do not edit by hand. "
        "The verdicts:",
        "",
        *(f"- **{k}**: {m}." for k, m in LEGEND.items()),
        "",
        *textwrap.wrap(_interval_note(results, interval), WIDTH),
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


def _interval_note(results: Path, interval: str) -> str:
    """Which intervals decide the claims that compare intervals, with the coverage the
    interval-coverage study measured for each at 5 runs, when it has run."""
    # here, not above: that study's module imports scipy.stats, which checking options does not need
    from repro.studies.verdicts.interval_coverage import NAME as COVERAGE

    other = next(k for k in INTERVALS if k != interval)
    text = (f"Claims that compare 95% intervals over runs are decided with the **{interval}** "
            f"intervals (`claims --interval`, {' or '.join(INTERVALS)}); beside the verdict, "
            f"the verdict under the {other} intervals (with its value where that differs).")
    path = results / f"{COVERAGE}.csv"
    try:
        cov = read_result(path)
        scale_of(path)
    except FileNotFoundError:
        return text + f" Their coverage: not yet measured (`make {COVERAGE.replace('_', '-')}`)."
    cov = cov[(cov.n == 5) & (cov.confidence == 0.95) & cov.kind.isin(INTERVALS)]
    parts = [f"{statistic}: " + ", ".join(
        f"{kind} " + "/".join(f"{x:.1%}" for x in g.coverage) for kind, g in s.groupby(
            "kind", sort=False)) for statistic, s in cov.groupby("statistic", sort=False)]
    return (text + f" Measured coverage of a nominal 95% interval from 5 runs per group "
            f"(`{COVERAGE}.csv`, {int(cov.trials.iloc[0]):,} samples each; populations "
            f"{'/'.join(dict.fromkeys(cov.population))}): " + "; ".join(parts) + ".")


def _tally(rows: list[tuple[Claim, Verdict]]) -> str:
    counts = {k: sum(v.verdict == k for _, v in rows) for k in VERDICTS}
    return ", ".join(f"{n} {k}" for k, n in counts.items() if n)


def _scales(rows: list[tuple[Claim, Verdict]]) -> str:
    return " and ".join(sorted({v.scale for _, v in rows if v.scale})) or "no"


def _table(rows: list[tuple[Claim, Verdict]]) -> list[str]:
    lines = []
    for c, v in rows:
        where = f" ({c.where})" if c.where else ""
        verdict = f"**{v.verdict}**" + (f" ({v.other})" if v.other else "")
        lines.append("| " + " | ".join(_cell(x) for x in (
            c.id, c.text, c.paper + where, v.ours, verdict)) + " |")
    return lines


def _details(rows: list[tuple[Claim, Verdict]]) -> list[str]:
    lines = []
    for c, v in rows:
        lines += ["", f"### {c.id}: {v.verdict}" + (f" ({v.scale} scale)" if v.scale else ""), ""]
        other = (f" With the other intervals, {v.other}" + (f" ({v.other_ours})" if v.other_ours
                                                              else "") + "." if v.other else "")
        lines += textwrap.wrap(f"Tolerance: {c.tolerance}. {v.detail or ''}{other}", WIDTH,
                               break_on_hyphens=False)
        lines.append(f"Regenerate: `{c.command}`.")
    return lines


WIDTH = 100
"""Line width of the details."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--results-dir", default=DEFAULT_RESULTS,
                   help=f"folder the checks read (default {DEFAULT_RESULTS})")
    p.add_argument("--interval", default=INTERVALS[0],
                   help=f"the 95%% intervals that decide the claims that compare intervals: "
                   f"{' or '.join(INTERVALS)} (default {INTERVALS[0]}, whose coverage at 5 runs "
                   f"the interval-coverage study checks)")
    p.add_argument("--out", help=f"the rendered table, a Markdown file (.md; default "
                   f"{PAPER_CLAIMS} for a complete set of paper-scale results, in the checkout "
                   f"for {DEFAULT_RESULTS} and in --results-dir for another folder; otherwise a "
                   f"smoke check, <results-dir>/{SMOKE_OUT}, never {PAPER_CLAIMS})")


@dataclass(frozen=True)
class ClaimsCommand:
    """What ``claims`` renders from, and where."""

    results: Path
    """The folder of result files the checks read (``--results-dir``)."""
    interval: str
    """The 95% intervals that decide the claims that compare intervals (``--interval``)."""
    out: str | None
    """The rendered table, a Markdown file (``--out``; None: by what the results are)."""


def configure(args: argparse.Namespace) -> ClaimsCommand:
    require(args.results_dir.strip() != "", "--results-dir",
            "a folder of result files (not an empty path)", args.results_dir)
    require(args.interval in INTERVALS, "--interval", " or ".join(INTERVALS), args.interval)
    results = Path(args.results_dir)
    # a mistyped or empty folder would otherwise render a table of "not yet run" over the claims
    require(results.is_dir() and any(results.glob("*.provenance.json")), "--results-dir",
            "an existing folder of result files (CSVs with their provenance sidecars)",
            str(results))
    require(args.out is None or args.out.strip() != "", "--out", "a file name", args.out)
    # a Markdown name: never a result's CSV or sidecar
    require(args.out is None or args.out.endswith(".md"), "--out",
            "a Markdown file name ending in .md (never a result CSV or sidecar)", args.out)
    return ClaimsCommand(results=results, interval=args.interval, out=args.out)


def run(cmd: ClaimsCommand) -> int:
    results = cmd.results
    evaluated = evaluate_all(results, cmd.interval)
    paper = is_paper_set(results, evaluated)
    if not paper:
        default = str(results / SMOKE_OUT)
    elif results.resolve() == Path(DEFAULT_RESULTS).resolve():
        default = PAPER_CLAIMS
    else:  # the checkout's paper_claims.md describes results/paper only
        default = str(results / PAPER_CLAIMS)
    out = check_names(default if cmd.out is None else cmd.out, "--out")
    missing = missing_claims(evaluated)
    why = (f"results of the {' and '.join(sorted(result_scales(results)))} scale"
           if not is_paper_scale(results) else
           f"an incomplete set of paper-scale results ({', '.join(missing)} without their files)")
    require(paper or out.name != PAPER_CLAIMS, "--out", f"another file than {PAPER_CLAIMS} for "
            f"{why} ({PAPER_CLAIMS} is rendered from a complete set of paper-scale results only)",
            str(out))
    require(not out.is_dir(), "--out", "a file, not a folder", str(out))
    check_writable_dir(out.parent, "--out")
    text = render(results, cmd.interval, evaluated)
    write_text(out, text)
    if not paper:  # the smoke check's table, for the end of `make reproduce`
        print(text.split("\n## Details")[0].rstrip())
    print(f"wrote {out}")
    return 0
