"""C6-C9: wildfire behaviour and transfer.

Interval estimates are over the trained policies (seeds). C8 and C9 compare the 95% CIs of the
mean of :func:`repro.claims.interval_kind` (t, or the drivers' percentile bootstrap); C6 and C7,
decided on means, show percentile bootstrap CIs (``repro.runs.stats.bootstrap_ci``) with a fixed
generator, so the rendered table is reproducible. C6 and C7 are decided on the crowding penalty
that fits the paper's numbers best (``wildfire-penalty``: the paper's policy was trained with a
penalty nobody recorded), the behaviour study's fixed-penalty readings beside.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from repro.claims import (NOT_RUN, Claim, Reading, Verdict, at_most_partial, decided_on,
                          interval_name, scale_of, side_by_side, with_intervals)
from repro.envs.wildfire import FIGURE_VERSION, QUIRKS, version_suffix
from repro.paper import BEHAVIOUR_FREQUENCIES, C9_PAIR, FLOWCHART_WORSE, TRANSFER_ADR
from repro.runs.results import read_provenance, read_result
from repro.runs.stats import bootstrap_ci, ci_side

C6_TOLERANCE = 0.10
"""Each C6 frequency must lie within 10 percentage points of the paper's."""
C7_BAND = (0.18, 0.38)
"""C7 reproduces fully when the flowchart is 28% +- 10 points worse than the learned policy."""
C8_SAME = ("FS-0.1", "FS-0.316", "FS-1")
"""FS simulators whose policies transfer as well as ED-trained ones (paper)."""
C8_WORSE = ("FS-3.16", "FS-10")
"""FS simulators whose policies degrade on ED (paper)."""
C9_PAPER = " vs ".join(f"{TRANSFER_ADR[label][0]:.3f}" for label in C9_PAIR)
"""C9 as the paper gives it: the pair's ADR on ED."""
_B = {key: round(100 * value) for key, value in BEHAVIOUR_FREQUENCIES.items()}
"""C6's percentages."""


RELEASED_SINCE = "2026-11-25T03:16:00Z"
"""When the wildfire engines began to follow the released simulator's same-instant semantics
(Q3-Q6, its order). A wildfire result finished before then was made on the earlier semantics: it
does not answer a claim about today's engines, so it reads "not yet run", with what it showed."""


def made_before_released_semantics(path: Path) -> bool:
    """Whether the wildfire result ``path`` (its sidecar's finish time) predates RELEASED_SINCE."""
    return read_provenance(path).get("finished_utc", "") < RELEASED_SINCE


def on_current_semantics(check: Callable[[Path, str], Verdict],
                         stem: str) -> Callable[[Path, str], Verdict]:
    """``check``, unless its result file ``stem`` (``{}`` standing for the reading's suffix)
    predates the released semantics: then "not yet run", keeping the old verdict and numbers in
    the detail."""
    def checked(results: Path, suffix: str = "") -> Verdict:
        v = check(results, suffix)
        if not made_before_released_semantics(results / stem.format(suffix)):
            return v
        return Verdict(f"earlier semantics: {v.ours}", NOT_RUN,
                       f"Not yet rerun since the engines follow the released simulator; "
                       f"on the earlier semantics it read {v.verdict}: {v.detail}", v.scale,
                       outdated=True)
    return checked


def _ci(x: np.ndarray) -> tuple[float, float, float]:
    return bootstrap_ci(x, np.mean, n_boot=2000, rng=np.random.default_rng(0))


def _pct(x: float) -> str:
    return f"{100 * x:.0f}%"


def check_c6(results: Path, suffix: str = "") -> Verdict:
    path = results / f"wildfire_behaviour{suffix}.csv"
    t = read_result(path)
    parts, ok = [], []
    for key, paper in BEHAVIOUR_FREQUENCIES.items():
        mean, lo, hi = _ci(t[key].to_numpy())
        ok.append(abs(mean - paper) <= C6_TOLERANCE)
        parts.append(f"{key} {_pct(mean)} [{_pct(lo)}, {_pct(hi)}] (paper {_pct(paper)})")
    verdict = "PASS" if all(ok) else "PARTIAL" if any(ok) else "FAIL"
    outside = [k for k, good in zip(BEHAVIOUR_FREQUENCIES, ok) if not good]
    ours = ", ".join(f"{_pct(t[k].mean())}" for k in BEHAVIOUR_FREQUENCIES)
    limit = int(t.get("max_decisions", pd.Series([0])).iloc[0])
    detail = (f"{len(t)} policies x {t.epochs.iloc[0]} epochs x {_batch(t)} on ED{_limit(limit)}, "
              f"measured on {t.test_episodes.iloc[0]} ED episodes "
              f"each; mean over policies [95% bootstrap CI]: " + "; ".join(parts)
              + f". Outside tolerance: {outside or 'none'}."
              + _without_stays(t, results / f"wildfire_behaviour{suffix}_flowchart.csv"))
    return Verdict(ours, verdict, detail, scale_of(path))


PENALTY = "wildfire_penalty.csv"
"""The behaviour study over crowding penalties (``wildfire-penalty``): the set-up of the paper's
C6 numbers, whose penalty is unknown, fitted."""


FITTED = "the fitted crowding penalty (wildfire-penalty)"
"""C6's and C7's deciding set-up, as their details name it."""


def _best_penalty(results: Path) -> tuple[pd.DataFrame, pd.DataFrame, float, Path]:
    """The penalty table, its authors'-definition fit rows and the best-fitting penalty."""
    path = results / PENALTY
    table, fit = read_result(path), read_result(results / PENALTY.replace(".csv", "_fit.csv"))
    fit = fit[fit.definitions == "authors"]
    return table, fit, float(fit[fit.best].penalty.iloc[0]), path


def check_c6_penalty(results: Path) -> Verdict:
    """C6 on the best-fitting penalty's policies, each measured as the authors measured theirs
    (their definitions, 500 sampled episodes); every penalty's distance to the paper beside."""
    table, fit, best, path = _best_penalty(results)
    t = table[table.penalty == best]
    parts, ok = [], []
    for key, paper in BEHAVIOUR_FREQUENCIES.items():
        mean, lo, hi = _ci(t["authors_" + key].to_numpy())
        ok.append(abs(mean - paper) <= C6_TOLERANCE)
        parts.append(f"{key} {_pct(mean)} [{_pct(lo)}, {_pct(hi)}] (paper {_pct(paper)})")
    verdict = "PASS" if all(ok) else "PARTIAL" if any(ok) else "FAIL"
    ours = f"penalty {best:g}: " + ", ".join(_pct(t["authors_" + k].mean())
                                             for k in BEHAVIOUR_FREQUENCIES)
    fits = "; ".join(f"{r.penalty:g}: {r.rms_distance:.3f} (largest {r.max_distance:.2f})"
                     for r in fit.itertuples())
    paper = np.array(list(BEHAVIOUR_FREQUENCIES.values()))
    each = np.sqrt(((table[[f"authors_{k}" for k in BEHAVIOUR_FREQUENCIES]].to_numpy() - paper)
                    ** 2).mean(axis=1))
    one = table.iloc[int(np.argmin(each))]
    closest = (f" The single policy closest to the paper's (the paper measured one): penalty "
               f"{one.penalty:g}, seed {int(one.train_seed)}, RMS distance {each.min():.3f}: "
               + ", ".join(_pct(one["authors_" + k]) for k in BEHAVIOUR_FREQUENCIES) + ".")
    detail = (f"Crowding penalty fitted: of {', '.join(f'{p:g}' for p in fit.penalty)}, the one "
              f"whose policies' six numbers lie closest to the paper's (RMS distance; one "
              f"parameter fitted on six numbers). RMS distance per penalty: {fits}. At penalty "
              f"{best:g}: {len(t)} policies x {t.epochs.iloc[0]} epochs on ED, each measured as "
              f"the authors' script did (at a fire: distance < 1e-7; alone: party 1, shared: "
              f"above 1; closest cluster = fly ranks 1-3) on {t.authors_episodes.iloc[0]} "
              f"sampled episodes; mean over policies [95% bootstrap CI]: " + "; ".join(parts)
              + f". Outside tolerance: "
              f"{[k for k, good in zip(BEHAVIOUR_FREQUENCIES, ok) if not good] or 'none'}."
              + closest)
    return Verdict(ours, verdict, detail, scale_of(path))


def check_c7_penalty(results: Path) -> Verdict:
    """C7 on the best-fitting penalty's policies (:func:`check_c6_penalty`)."""
    table, _, best, path = _best_penalty(results)
    t = table[table.penalty == best]
    v = _c7(t, path)
    return dataclasses.replace(v, ours=f"penalty {best:g}: {v.ours}")


def _batch(t: pd.DataFrame) -> str:
    """A behaviour table's batch: decisions for a learner that counts them, else episodes."""
    decisions = int(t.get("batch_decisions", pd.Series([0])).iloc[0])
    return (f"{decisions} decisions" if decisions else f"{int(t.batch_episodes.iloc[0])} episodes")


def _limit(max_decisions: int) -> str:
    return f" (at most {max_decisions} decisions per UAV and episode)" if max_decisions else ""


def _without_stays(t: pd.DataFrame, flow_path: Path) -> str:
    """The frequencies without stay flights (flights to the fire the UAV is at), the learned
    policies' beside the flowchart's (the paper's probabilities, ``flow_path``); empty for older
    results."""
    if "stay_flight" not in t or not flow_path.exists():
        return ""
    flow = read_result(flow_path).iloc[0]
    pairs = "; ".join(f"{k} {_pct(t[k + '_ex_stay'].mean())} vs {_pct(flow[k + '_ex_stay'])}"
                      for k in BEHAVIOUR_FREQUENCIES)
    return (f" Stay flights (to the fire the UAV is at; they take no time) are "
            f"{_pct(t.stay_flight.mean())} of the learned policies' decisions and "
            f"{_pct(flow.stay_flight)} of the flowchart's. Without them, learned vs flowchart (the "
            f"paper's probabilities, same test episodes): {pairs}.")


def check_c7(results: Path, suffix: str = "") -> Verdict:
    path = results / f"wildfire_behaviour{suffix}.csv"
    return _c7(read_result(path), path)


def _c7(t: pd.DataFrame, path: Path) -> Verdict:
    """C7 from a behaviour table's policies (``path`` its file)."""
    if (t.adr_learned <= 0).any():  # the ratio's sign no longer says which policy is better
        return Verdict("-", "FAIL", f"a learned policy's ADR is not positive "
                       f"({t.adr_learned.min():.3f}): the ratio of ADRs is undefined",
                       scale_of(path))
    mean, lo, hi = _ci(t.flowchart_worse.to_numpy())
    verdict = ("PASS" if C7_BAND[0] <= mean <= C7_BAND[1] else
               "PARTIAL" if (t.flowchart_worse > 0).all() else "FAIL")
    detail = (f"1 - ADR(flowchart)/ADR(learned) per policy, same ED episodes; mean "
              f"{_pct(mean)} [{_pct(lo)}, {_pct(hi)}] over {len(t)} policies; learned ADR "
              f"{t.adr_learned.mean():.3f}, flowchart {t.adr_flowchart.iloc[0]:.3f}. PARTIAL: "
              f"flowchart worse for every policy but by a different amount")
    return Verdict(f"{_pct(mean)} worse", verdict, detail, scale_of(path))


def _summary(results: Path, stem: str) -> tuple[pd.DataFrame, Path]:
    path = results / f"{stem}_summary.csv"
    return with_intervals(read_result(path)).set_index("simulator"), path


def c8_verdict(s: pd.DataFrame) -> tuple[str, str]:
    """Transfer as well as ED: CIs overlap ED's; degrade: CI entirely below ED's.

    "As well as" is read as the paper found it, indistinguishable from ED: a CI entirely above
    ED's fails too, and the detail says so, since it is a different finding from a CI below."""
    ed = s.loc["ED"]
    side = {k: ci_side(s.loc[k], ed) for k in (*C8_SAME, *C8_WORSE)}
    checks = {**{k: side[k] == "overlapping" for k in C8_SAME},
              **{k: side[k] == "below" for k in C8_WORSE}}
    verdict = "PASS" if all(checks.values()) else "PARTIAL" if any(checks.values()) else "FAIL"
    failed = [f"{k} (CI {side[k]} ED's)" for k, good in checks.items() if not good]
    return verdict, f"failed: {', '.join(failed) or 'none'}"


def _means(s: pd.DataFrame) -> str:
    return ", ".join(f"{k} {r['mean']:.3f}+-{r['sem']:.3f}" for k, r in s.iterrows())


def _cis(s: pd.DataFrame) -> str:
    return "; ".join(f"{k} [{r.ci_low:.3f}, {r.ci_high:.3f}]" for k, r in s.iterrows())


def check_c8(results: Path, suffix: str = "") -> Verdict:
    s, path = _summary(results, f"transfer{suffix}")
    verdict, why = c8_verdict(s)
    verdict, caveat = at_most_partial(verdict, int(s.n_policies.min()))
    detail = (f"{int(s.n_policies.min())} policies per simulator, tested on ED (T_health = 3.0); "
              f"95% {interval_name()} CIs of the mean: {_cis(s)}. {why}.{caveat}")
    detail += _kept_line(s)
    detail += _cut_line(results / f"transfer{suffix}.csv")
    if suffix == AUTHORS_HEAD.suffix:  # the heuristics were tested on the released simulator
        detail += _heuristics_line(results)
    detail += _corrected_line(results, c8_verdict, means=True, suffix=suffix)
    return Verdict(_means(s.drop(index=C9_PAIR[0])), verdict, detail, scale_of(path))


def _kept_line(s: pd.DataFrame) -> str:
    """The same policies under the released runner's evaluation (the mean over the last 40
    epochs' policies, one episode each), when the summary has it."""
    if "mean_kept" not in s:
        return ""
    return (" Under the released runner's evaluation (last 40 policies, one ED episode each): "
            + ", ".join(f"{k} {r.mean_kept:.3f}+-{r.sem_kept:.3f}" for k, r in s.iterrows())
            + ".")


def _heuristics_line(results: Path) -> str:
    """The heuristic policies' ADR on the same ED test episodes, the baselines of the learned."""
    path = results / "wildfire_heuristics.csv"
    try:
        h = read_result(path)
        scale_of(path)
    except FileNotFoundError:
        return " Heuristics on the same test episodes: not yet run (`make wildfire-heuristics`)."
    parts = [f"{r.semantics} {r.policy} {r.adr:.3f}+-{r.sem:.3f}" for r in h.itertuples()]
    return f" Heuristics on the same ED test episodes: {', '.join(parts)}."


def c9_verdict(s: pd.DataFrame) -> tuple[str, str]:
    """Degrades: the T_health = 2.9999 CI lies entirely below the T_health = 3.0 one."""
    low, ref = s.loc[C9_PAIR[0]], s.loc[C9_PAIR[1]]
    ok = bool(low.ci_high < ref.ci_low)
    return ("PASS" if ok else "FAIL",
            f"{low['mean']:.3f} [{low.ci_low:.3f}, {low.ci_high:.3f}] vs "
            f"{ref['mean']:.3f} [{ref.ci_low:.3f}, {ref.ci_high:.3f}]")


def check_c9(results: Path, suffix: str = "") -> Verdict:
    s, path = _summary(results, f"transfer{suffix}")
    verdict, why = c9_verdict(s)
    verdict, caveat = at_most_partial(verdict, int(s.n_policies.min()))
    detail = (f"FS-1 trained with T_health = 2.9999 vs 3.0, both tested on ED, mean "
              f"[95% {interval_name()} CI]: {why}.{caveat}")
    if "mean_kept" in s:
        low, ref = s.loc[C9_PAIR[0]], s.loc[C9_PAIR[1]]
        detail += (f" Released runner's evaluation: {low.mean_kept:.3f}+-{low.sem_kept:.3f} vs "
                   f"{ref.mean_kept:.3f}+-{ref.sem_kept:.3f}.")
    detail += _corrected_line(results, c9_verdict, means=False, suffix=suffix)
    detail += _ablation_lines(results, suffix)
    low, ref = s.loc[C9_PAIR[0]], s.loc[C9_PAIR[1]]
    return Verdict(f"{low['mean']:.3f} vs {ref['mean']:.3f}", verdict, detail, scale_of(path))


def _ablation_lines(results: Path, suffix: str) -> str:
    """C9 on the ablations that switch single quirks off (``fig-transfer --no-quirk Q``)."""
    lines = []
    for quirk in (q.split("_")[1] for q in QUIRKS):
        path = results / f"transfer_no_{quirk}{suffix}_summary.csv"
        if not path.exists():
            continue
        s = with_intervals(read_result(path)).set_index("simulator")
        if set(C9_PAIR) <= set(s.index) and not made_before_released_semantics(path):
            verdict, why = c9_verdict(s)
            lines.append(f" Released semantics with {quirk.upper()} off "
                         f"({int(s.n_policies.min())} policies each): {verdict}: {why}.")
    return "".join(lines)


def _corrected_line(results: Path, judge, means: bool, suffix: str) -> str:
    """The same check on the run with quirks Q1-Q6 corrected, when it exists."""
    try:
        s, path = _summary(results, f"transfer_corrected{suffix}")
    except FileNotFoundError:
        return ""
    verdict, why = judge(s)
    verdict, caveat = at_most_partial(verdict, int(s.n_policies.min()))
    shown = f"{_means(s)}; " if means else ""
    if made_before_released_semantics(path):
        return (f" Corrected semantics: not yet rerun since Q3-Q6 and the released order were "
                f"added; before, with Q1, Q2 off, it read {verdict}: {shown}{why}.{caveat}")
    return (f" Corrected semantics (Q1-Q6 off; {scale_of(path)} scale): {verdict}: {shown}{why}."
            f"{caveat}{_cut_line(results / f'transfer_corrected{suffix}.csv') if means else ''}")


def _cut_line(per_policy: Path) -> str:
    """How many training and test episodes the decision limit cut (docs/semantics.md section
    3.7), when the per-policy table records it."""
    try:
        t = read_result(per_policy)
    except FileNotFoundError:  # not yet run, or a torn pair
        t = pd.DataFrame()
    if not {"train_truncated", "test_truncated"} <= set(t.columns):
        return ""
    train = int((t.epochs * t.batch_episodes).sum())
    test = int(t.test_episodes.sum())
    cut_train, cut_test = int(t.train_truncated.sum()), int(t.test_truncated.sum())
    if cut_train == cut_test == 0:
        return (f" No episode reached the decision limit ({int(t.max_decisions.iloc[0])} "
                f"decisions per UAV) in training or test.")
    return (f" The decision limit ({int(t.max_decisions.iloc[0])} decisions per UAV) cut "
            f"{cut_train:,} of {train:,} training episodes ({cut_train / train:.1%}) and "
            f"{cut_test:,} of {test:,} test episodes ({cut_test / max(test, 1):.1%}).")


BEHAVIOUR, TRANSFER = "wildfire_behaviour{}.csv", "transfer{}_summary.csv"
AUTHORS_HEAD = Reading("authors' learner, released simulator (2017-05-16)", "")
AUTHORS_APRIL = Reading("authors' learner, simulator of 2017-04-22 (crowding penalty 1)",
                        "_" + "_".join(version_suffix(FIGURE_VERSION)))
AUTHORS_APRIL_POOL = Reading("authors' learner, simulator of 2017-04-22, released pool",
                             AUTHORS_APRIL.suffix + "_pool")
SUITE = Reading("suite's learner, released simulator", "_suite")
TRANSFER_READINGS = (AUTHORS_APRIL_POOL, AUTHORS_APRIL, AUTHORS_HEAD, SUITE)
"""C8 and C9 are decided on the set-up the transfer runs were trained on: the simulator of
2017-04-22 and the released runner's unseeded pool of 40 workers."""
BEHAVIOUR_READINGS = (AUTHORS_HEAD, AUTHORS_APRIL, SUITE)
"""C6 and C7 are decided on the released simulator, the version their evidence points to
(docs/semantics.md section 3.13)."""

CLAIMS = [
    Claim("C6", f"Long ED training: hold shared {_B['hold_shared']}%, alone {_B['hold_alone']}%; "
          f"fly 1st/2nd/3rd {_B['fly_rank_1']}/{_B['fly_rank_2']}/{_B['fly_rank_3']}%; "
          f"closest cluster {_B['closest_cluster']}%",
          f"{_B['hold_shared']}%, {_B['hold_alone']}%, "
          f"{_B['fly_rank_1']}/{_B['fly_rank_2']}/{_B['fly_rank_3']}%, {_B['closest_cluster']}%",
          "each within 10 percentage points (mean over policies)",
          "make wildfire-penalty wildfire-behaviour",
          decided_on(check_c6_penalty, FITTED,
                     side_by_side(on_current_semantics(check_c6, BEHAVIOUR),
                                  BEHAVIOUR_READINGS)),
          where="Sec. 5.2, Fig. 6"),
    Claim("C7", f"The flowchart of C6 does {FLOWCHART_WORSE:.0%} worse than the learned policy "
          "(ADR)",
          f"{FLOWCHART_WORSE:.0%} worse", "PASS: 18-38% worse; PARTIAL: worse for every policy",
          "make wildfire-penalty wildfire-behaviour",
          decided_on(check_c7_penalty, FITTED,
                     side_by_side(on_current_semantics(check_c7, BEHAVIOUR),
                                  BEHAVIOUR_READINGS)), where="Sec. 5.2"),
    Claim("C8", "Trained on FS with dT <= 1 s transfers to ED; dT = 3.16, 10 s degrade",
          ", ".join(f"{label} {mean:.3f}" for label, (mean, _) in TRANSFER_ADR.items()
                    if label != C9_PAIR[0]),
          "95% CIs of FS-0.1/0.316/1 overlap ED's; those of FS-3.16/10 lie below ED's",
          "make transfer-pool",
          side_by_side(on_current_semantics(check_c8, TRANSFER), TRANSFER_READINGS),
          where="Fig. 7", intervals=True),
    Claim("C9", "FS-1 with T_health = 2.9999 degrades on ED", C9_PAPER,
          "95% CI of FS-1(2.9999) entirely below FS-1(3.0)'s",
          "make transfer-pool",
          side_by_side(on_current_semantics(check_c9, TRANSFER), TRANSFER_READINGS),
          where="Fig. 7", intervals=True),
]
