"""What the learner decides: the transfer figure point by point for each learner and simulator
version, the ablation one learner setting at a time, the inputs C9's failing policies depend on,
and question X5 (docs/semantics.md sections 5.7, 6.13 and 6.14)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from repro.claims import (Claim, Verdict, at_most_partial, interval_name, is_incomplete,
                          scale_of, with_difference_intervals)
from repro.claims.wildfire import C9_PAPER
from repro.paper import C9_PAIR, TRANSFER_ADR
from repro.runs.results import read_result
from repro.studies.transfer.c9_inputs import NAME as INPUTS
from repro.studies.transfer.learner_ablation import NAME as ABLATION
from repro.studies.transfer.study import distance_in_se

X5_SETTING = "observation normalisation"
"""The ablation row X5's hypothesis is about."""
FIGURE_COLUMNS = {  # transfer study stem -> column heading
    "transfer_20170422": "authors' learner, simulator of 2017-04-22",
    "transfer": "authors' learner, released simulator",
    "transfer_suite": "suite's learner, released simulator",
}


def check_x5(results: Path) -> Verdict:
    """C9's degradation (FS-1 T_health 2.9999 minus FS-1, final policy) with observation
    normalisation on: PASS when its CI lies below 0 as it does without; FAIL when it does not."""
    path = results / f"{ABLATION}_c9.csv"
    e = read_result(path)
    e = with_difference_intervals(e[e.protocol == "final policy"],
                                  results / f"{ABLATION}.csv", ["setting"],
                                  C9_PAIR).set_index("setting")
    row, base = e.loc[X5_SETTING], e.loc["authors"]
    verdict = "PASS" if row.degrades else "FAIL"
    verdict, caveat = at_most_partial(verdict, int(e.n_policies.min()))
    parts = [f"{k}: {r.difference:+.3f} [{r.ci_low:+.3f}, {r.ci_high:+.3f}]"
             for k, r in e.iterrows()]
    detail = (f"C9's degradation (mean ADR on ED of FS-1 trained with T_health 2.9999 minus "
              f"FS-1 with 3.0, final policies, 95% {interval_name()} CI) per learner setting, "
              f"from the authors' learner on the simulator of 2017-04-22: {'; '.join(parts)}. "
              f"Without normalisation it {'degrades' if base.degrades else 'does not degrade'}."
              f"{caveat}")
    return Verdict(f"{row.difference:+.3f} [{row.ci_low:+.3f}, {row.ci_high:+.3f}] with "
                   f"normalisation vs {base.difference:+.3f} without", verdict, detail,
                   scale_of(path))


def _section(title: str, intro: str, columns: list[str]) -> list[str]:
    """A notes section's heading, its paragraph and the head of its table."""
    return ["", f"## {title}", "", intro, "", "| " + " | ".join(columns) + " |",
            "|---" * len(columns) + "|"]


def _figure_table(results: Path) -> list[str]:
    """The transfer figure per training simulator: the paper, each learner and version (mean
    +- SEM over policies, distance to the paper in combined SEs)."""
    frames = {}
    for stem, heading in FIGURE_COLUMNS.items():
        path = results / f"{stem}_summary.csv"
        try:
            frames[heading] = read_result(path).set_index("simulator")
        except FileNotFoundError:  # not yet run, or a torn pair
            continue
    if not frames:
        return []
    lines = _section("The learner decides: the transfer figure point by point",
                     "ADR on ED (T_health 3.0), mean +- SEM over policies, and in brackets the "
                     "distance to the paper's point in combined standard errors. The authors' "
                     "learner is scored on the final policy (10,000 episodes) and, second, as the "
                     "released runner scored it (the last 40 epochs' policies, one episode each).",
                     ["trained on", "paper", *frames])
    for label, (mean, err) in TRANSFER_ADR.items():
        cells = []
        for heading, s in frames.items():
            if label not in s.index:
                cells.append("-")
                continue
            r = s.loc[label]
            z = distance_in_se(r["mean"], r["sem"], mean, err)
            cell = f"{r['mean']:.3f} +- {r['sem']:.3f} ({z:+.1f})"
            if "mean_kept" in s and heading.startswith("authors"):
                cell += (f"; {r.mean_kept:.3f} +- {r.sem_kept:.3f} "
                         f"({distance_in_se(r.mean_kept, r.sem_kept, mean, err):+.1f})")
            cells.append(cell)
        lines.append(f"| {label} | {mean:.3f} +- {err:.3f} | " + " | ".join(cells) + " |")
    return lines


def _ablation_table(results: Path) -> list[str]:
    """The ablation summary: per setting and training simulator, mean +- SEM (distance to the
    paper), and C9's degradation per setting."""
    path = results / f"{ABLATION}_summary.csv"
    if not path.exists():
        return []
    s = read_result(path)
    sims = list(dict.fromkeys(s.simulator))
    lines = _section(f"One learner setting at a time ({scale_of(path)} scale)",
                     "From the authors' learner on the simulator of 2017-04-22, one setting "
                     "changed to the suite's (`make learner-ablation`); ADR on ED, final policies, "
                     "mean +- SEM (distance to the paper in combined SEs); last column: C9's "
                     "degradation, FS-1 (2.9999) minus FS-1, with its 95% bootstrap CI.",
                     ["setting", *sims, "C9 degradation"])
    c9_path = results / f"{ABLATION}_c9.csv"
    try:
        c9 = read_result(c9_path)
    except FileNotFoundError:  # not yet run, or a torn pair
        c9 = pd.DataFrame(columns=["setting"])
    c9 = c9[c9.get("protocol", pd.Series(dtype=str)) == "final policy"].set_index("setting")
    for setting, g in s.groupby("setting", sort=False):
        g = g.set_index("simulator")
        cells = [f"{g.loc[k, 'mean']:.3f} +- {g.loc[k, 'sem']:.3f} ({g.loc[k, 'z_paper']:+.1f})"
                 if k in g.index else "-" for k in sims]
        gap = (f"{c9.loc[setting, 'difference']:+.3f} [{c9.loc[setting, 'ci_low']:+.3f}, "
               f"{c9.loc[setting, 'ci_high']:+.3f}]" if setting in c9.index else "-")
        lines.append(f"| {setting} | " + " | ".join(cells) + f" | {gap} |")
    return lines


def _inputs_table(results: Path) -> list[str]:
    """c9-inputs: the ADR change when an input group is clamped at test time."""
    path = results / f"{INPUTS}_summary.csv"
    if not path.exists():
        return []
    s = read_result(path)
    s = s[s.clamp != "none"]
    lines = _section(f"Which inputs C9's policies depend on ({scale_of(path)} scale)",
                     "Authors' learner, simulator of 2017-04-22 (`make c9-inputs`): ADR on ED with "
                     "an input group clamped at test time minus the unclamped policy's (same "
                     "episodes, same action stream), mean over policies with its 95% bootstrap "
                     "CI, and the share of decisions whose observation the clamp changed.",
                     ["trained on", "clamp", "ADR", "change", "decisions changed"])
    return lines + [f"| {r.simulator} | {r.clamp} | {r.adr_ed:.3f} | {r.change:+.3f} "
                    f"[{r.ci_low:+.3f}, {r.ci_high:+.3f}] | {r.changed_share:.0%} |"
                    for r in s.itertuples()]


def NOTES(results: Path) -> str:  # noqa: N802 (the registry's name for a topic's notes)
    lines: list[str] = []
    for table in (_figure_table, _ablation_table, _inputs_table):
        try:
            lines += table(results)
        except FileNotFoundError:  # a CSV without its sidecar: not yet run
            pass
        except Exception as err:  # a stale or hand-edited file, as in Claim.evaluate
            if not is_incomplete(err):
                raise
            lines += ["", f"({table.__doc__.split(':')[0]}: results incomplete, "
                      f"{type(err).__name__})"]
    return "\n".join(lines)


CLAIMS = [
    Claim("X5", "C9's degradation is a property of the fixed time step, not of the learner: it "
          "survives observation normalisation",
          f"C9: {C9_PAPER} (the paper's learner has no normalisation)",
          "with normalisation on, the 95% CI of FS-1 (2.9999) minus FS-1 lies below 0",
          "make learner-ablation", check_x5, where="Fig. 7", intervals=True),
]
