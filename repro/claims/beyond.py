"""Beyond the paper: questions the paper raises and leaves open, checked like its claims
and rendered in a section of their own. A verdict says whether the hypothesis in the table holds.

Intervals are 95% CIs of the mean over seeds, of :func:`repro.claims.interval_kind` (t, or the
drivers' percentile bootstrap); with one run per setting a verdict is at most PARTIAL.
"""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from repro.claims import (LEARNER_READINGS, NOT_RUN, Claim, Verdict, at_most_partial,
                          interval_name, scale_of, side_by_side, with_intervals)
from repro.runs.results import read_result
from repro.runs.stats import ci_side
from repro.studies.advantage.estimators import REFERENCE
from repro.studies.transfer.dt_grid import RACES, TransferDtConfig, read_races

RACE_ONSET = 0.1
"""Races have begun at the dT where the nearest policy's races per decision reach 0.1, C10's
delta."""
ONSET_WINDOW = 0.25
"""X3's hypothesis holds when transfer breaks within this many decades of the race onset: one
step of the grid."""


def _num(x: float) -> str:
    return f"{x:.0f}" if abs(x) >= 100 else f"{x:.3f}"


def check_x1(results: Path, suffix: str = "") -> Verdict:
    """M-GAE against each other estimator, per environment: PASS when M-GAE's CI lies above every
    other's, PARTIAL above some, FAIL none."""
    path = results / f"beyond_mgae{suffix}_summary.csv"
    s = with_intervals(read_result(path), runs="n_runs")
    parts, beats, ours = [], [], []
    for env, grp in s.groupby("env", sort=False):
        ref = grp[grp.estimator == REFERENCE].iloc[0]
        others = grp[grp.estimator != REFERENCE]
        sides = {r.estimator: ci_side(ref, r) for r in others.itertuples()}
        beats += [side == "above" for side in sides.values()]
        cis = "; ".join(f"{r.estimator} {_num(r.mean)} [{_num(r.ci_low)}, {_num(r.ci_high)}]"
                        for r in grp.itertuples())
        vs = ", ".join(f"{'overlaps' if side == 'overlapping' else side} {e}'s"
                       for e, side in sides.items())
        same = ("; duration-gae is M-GAE exactly at lambda = 1 (not trained)"
                if "duration-gae" not in set(grp.estimator) and ref.lam == 1 else "")
        parts.append(f"{env} (lambda = {ref.lam:g}, {int(grp.n_runs.min())} runs each): {cis}; "
                     f"M-GAE's CI: {vs}{same}")
        ours.append(f"{env}: " + ", ".join(f"{r.estimator} {_num(r.mean)}"
                                           for r in grp.itertuples()))
    verdict = "PASS" if all(beats) else "PARTIAL" if any(beats) else "FAIL"
    verdict, caveat = at_most_partial(verdict, int(s.n_runs.min()))
    detail = ("Score per run: bus final return (mean of the last epochs, as C1), wildfire ADR on "
              f"ED (as C8); mean [95% {interval_name()} CI] over runs. " + ". ".join(parts) + "."
              + caveat)
    return Verdict("; ".join(ours), verdict, detail, scale_of(path))


def _dt(dt: float | None) -> str:
    return "none" if dt is None else f"{dt:.3g} s"


def _rates_at(races: pd.DataFrame, dt: float | None) -> str:
    """X2's race rates of each policy at the measured dT nearest ``dt`` (log scale)."""
    if dt is None:
        return ""
    out = []
    for policy, grp in races.groupby("policy", sort=True):
        row = grp.iloc[(grp.dt.map(math.log10) - math.log10(dt)).abs().argmin()]
        # row["dt"]: a row's .dt is pandas' datetime accessor
        out.append(f"{policy} {row.races_per_decision:.3f} per decision, "
                   f"{row.p_race_episode:.3f} per episode (dT = {row['dt']:.3g} s)")
    return f" Races at {_dt(dt)}: " + "; ".join(out) + "."


def check_x3(results: Path, suffix: str = "") -> Verdict:
    """Transfer breaks from the smallest dT whose CI lies below ED's and holds up to the largest
    dT before it whose CI overlaps ED's; PASS when the break lies within ONSET_WINDOW of the race
    onset."""
    path = results / f"transfer_dt_grid{suffix}_summary.csv"
    s = with_intervals(read_result(path))
    ed = s[s.dt == 0].iloc[0]
    fs = s[s.dt > 0].sort_values("dt")
    side = {r.dt: ci_side(r, ed) for r in fs.itertuples()}
    breaks = min((dt for dt, x in side.items() if x == "below"), default=None)
    overlapping = [dt for dt, x in side.items() if x == "overlapping"]
    # "holds up to": the last dT before the break; a CI that overlaps ED's again beyond the break
    # (too few policies to resolve a degradation there) is named, not taken for a recovery
    holds = max((dt for dt in overlapping if breaks is None or dt < breaks), default=None)
    again = [dt for dt in overlapping if breaks is not None and dt > breaks]
    ours = (f"holds up to {_dt(holds)}, breaks from {_dt(breaks)}"
            + (f" (overlaps again at {', '.join(_dt(dt) for dt in again)})" if again else ""))
    detail = (f"{int(s.n_policies.min())} policies per simulator, tested on ED, mean [95% "
              f"{interval_name()} CI]; ED {ed['mean']:.3f} [{ed.ci_low:.3f}, {ed.ci_high:.3f}]; "
              "FS-dT against it: "
              + "; ".join(f"{dt:.3g} s {r['mean']:.3f} ({side[dt]})"
                          for dt, (_, r) in zip(side, fs.iterrows())) + ".")
    races = read_races(results, TransferDtConfig().race_agents)
    if races is None:
        return Verdict(ours, NOT_RUN, detail + f" Race rates: {RACES} missing (claim X2): the "
                       "figure draws the ADR alone, and whether transfer breaks where races "
                       "begin is not yet answered.", scale_of(path))
    nearest = races[races.policy == "nearest"]
    onset = next((r.dt for r in nearest.itertuples() if r.races_per_decision >= RACE_ONSET), None)
    ok = (breaks is not None and onset is not None
          and abs(math.log10(onset) - math.log10(breaks)) <= ONSET_WINDOW + 1e-9)
    verdict, caveat = at_most_partial("PASS" if ok else "FAIL", int(s.n_policies.min()))
    detail += (f" Races begin (nearest policy, {RACE_ONSET:g} races per decision) at "
               f"{_dt(onset)}.{_rates_at(races, holds)}{_rates_at(races, breaks)}{caveat}")
    return Verdict(f"{ours}; races begin at {_dt(onset)}", verdict, detail, scale_of(path))


CLAIMS = [
    Claim("X1", "Does M-GAE matter? PS-TRPO with M-GAE, decision-step GAE (one discount for the "
          "batch's mean duration) and duration-discounted GAE (lambda per decision), all else "
          "equal", "M-GAE beats both alternatives in both environments",
          "PASS: M-GAE's 95% CI lies above each alternative's; PARTIAL: above some; FAIL: none",
          "make beyond-mgae", side_by_side(check_x1, LEARNER_READINGS), where="Sec. 3.2",
          intervals=True),
    Claim("X3", "Where does transfer from FS-dT to ED break (13 dT from 0.01 to 10 s), and does it "
          "break where races begin?", "transfer breaks where races begin (X2's rate, N = 3)",
          f"PASS: the smallest dT whose CI lies below ED's is within {ONSET_WINDOW:g} decades of "
          f"the dT at which the nearest policy's races reach {RACE_ONSET:g} per decision",
          "make beyond-transfer-dt", side_by_side(check_x3, LEARNER_READINGS),
          where="Fig. 7, Sec. 5.3", intervals=True),
]
