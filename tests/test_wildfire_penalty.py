"""The behaviour study over crowding penalties (C6, C7): the authors' definitions on hand-made
decisions, the fit, the claim checks, and the command end to end at smoke scale."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from repro.claims import NOT_RUN
from repro.claims.wildfire import CLAIMS, check_c6_penalty
from repro.core.rollout import Rollout
from repro.envs.wildfire import WildfireConfig
from repro.envs.wildfire.params import DIST, FIRES, INTEREST, OBS_PER_FIRE, STATUS
from repro.paper import BEHAVIOUR_FREQUENCIES
from repro.studies.wildfire.penalty import SIX, authors_counts, authors_shares, fit
from tests.conftest import write_result_csv

CFG = WildfireConfig()
HOLD = CFG.n_observed


def _decisions(rows: list[tuple[float, float, float, int]]) -> Rollout:
    """A rollout of one path whose decisions have the closest fire's (distance, status, interest
    party) and the action given; the other observed fires are far and burning."""
    n = len(rows)
    obs = np.zeros((n, FIRES + OBS_PER_FIRE * CFG.n_observed))
    for j in range(CFG.n_observed):
        obs[:, FIRES + OBS_PER_FIRE * j + DIST] = 0.5 + j
        obs[:, FIRES + OBS_PER_FIRE * j + STATUS] = 1.0
    for i, (dist, status, party, _) in enumerate(rows):
        obs[i, FIRES + DIST], obs[i, FIRES + STATUS], obs[i, FIRES + INTEREST] = dist, status, party
    return Rollout(obs=obs, actions=np.array([r[3] for r in rows], np.int64),
                   rewards=np.zeros(n), durations=np.ones(n),
                   path_start=np.array([0, n], np.int64), path_episode=np.zeros(1, np.int64),
                   path_agent=np.zeros(1, np.int64), episode_return=np.zeros(1))


def test_authors_definitions_count_what_their_script_counts():
    ro = _decisions([
        (0.0, 1.0, 1, HOLD),      # at a live fire alone, holds
        (0.0, 1.0, 1, 2),         # at a live fire alone, flies to the 3rd closest
        (0.0, 1.0, 3, HOLD),      # shared, holds
        (0.0, 1.0, 2, 0),         # shared, flies to the fire it is at
        (0.0, 1.0, 0, HOLD),      # party 0: neither alone nor shared in their script
        (5e-3, 1.0, 1, HOLD),     # 5 mm away: at the fire for the suite, not for the authors
        (0.0, 0.0, 1, HOLD),      # at a dead fire
        (0.3, 1.0, 0, 1),         # away from fires, flies to the 2nd closest
    ])
    c = authors_counts(ro, CFG)
    assert (c["n_alone"], c["hold_alone_events"]) == (2, 1)
    assert (c["n_shared"], c["hold_shared_events"]) == (2, 1)
    assert c["n_fly"] == 3 and (c["fly_rank_1_events"], c["fly_rank_2_events"],
                                c["fly_rank_3_events"]) == (1, 1, 1)
    s = authors_shares(c)
    assert s["authors_hold_alone"] == 0.5 and s["authors_hold_shared"] == 0.5
    assert s["authors_closest_cluster"] == pytest.approx(1.0)  # ranks 1-3 together
    assert list(s) == [f"authors_{k}" for k in SIX]


def _table(penalties: dict[float, float]) -> pd.DataFrame:
    """Two policies per penalty, every number of both definitions the paper's plus an offset."""
    rows = []
    for penalty, offset in penalties.items():
        for seed in (0, 1):
            numbers = {k: v + offset for k, v in BEHAVIOUR_FREQUENCIES.items()}
            rows.append(dict(penalty=penalty, train_seed=seed, epochs=3000, authors_episodes=500,
                             **{f"authors_{k}": v for k, v in numbers.items()}, **numbers,
                             adr_learned=2.0, adr_flowchart=1.5, flowchart_worse=0.25))
    return pd.DataFrame(rows)


def test_fit_marks_the_closest_penalty_for_each_definition():
    out = fit(_table({1.0: 0.2, 5.0: -0.01, 20.0: 0.05}))
    assert len(out) == 6
    best = out[out.best]
    assert list(best.definitions) == ["authors", "suite"] and (best.penalty == 5.0).all()
    assert out[out.penalty == 1.0].rms_distance.iloc[0] == pytest.approx(0.2)


@pytest.mark.parametrize("offset, verdict", [(0.05, "PASS"), (0.2, "FAIL")])
def test_c6_is_decided_on_the_fitted_penalty(tmp_path, offset, verdict):
    table = _table({1.0: 0.4, 10.0: offset})
    write_result_csv(table, tmp_path / "wildfire_penalty.csv")
    write_result_csv(fit(table), tmp_path / "wildfire_penalty_fit.csv")
    v = check_c6_penalty(tmp_path)
    assert v.verdict == verdict and v.ours.startswith("penalty 10:")
    c6 = next(c for c in CLAIMS if c.id == "C6").evaluate(tmp_path)
    assert c6.verdict == verdict and "Beside it" in c6.detail


def test_c6_reads_not_yet_run_without_the_penalty_study(tmp_path):
    for claim in CLAIMS[:2]:
        assert claim.evaluate(tmp_path).verdict == NOT_RUN


@pytest.mark.slow
def test_the_command_end_to_end(tmp_path):
    """Two penalties at smoke scale: a row per policy, the fit, and a rerun skips the training
    and writes the same bytes."""
    from repro.cli import main

    args = ["wildfire-penalty", "--scale", "smoke", "--results-dir", str(tmp_path / "res"),
            "--runs-dir", str(tmp_path / "runs"), "--n-jobs", "1"]
    assert main(args) == 0
    table = pd.read_csv(tmp_path / "res" / "wildfire_penalty.csv")
    assert sorted(table.penalty) == [1.0, 20.0]
    assert {f"authors_{k}" for k in SIX} <= set(table.columns)
    assert sorted(p.name for p in (tmp_path / "runs" / "wildfire-penalty" / "smoke").iterdir()
                  if p.is_dir()) == ["pen1-ed-seed0", "pen20-ed-seed0"]
    before = (tmp_path / "res" / "wildfire_penalty.csv").read_bytes()
    assert main(args) == 0
    assert (tmp_path / "res" / "wildfire_penalty.csv").read_bytes() == before


@pytest.mark.parametrize("flag, value", [("--penalties", "-1"), ("--authors-episodes", "0"),
                                         ("--penalties", "1 1")])
def test_bad_input(tmp_path, flag, value):
    proc = subprocess.run([sys.executable, "-m", "repro", "wildfire-penalty", "--scale", "smoke",
                           flag, *value.split(), "--results-dir", str(tmp_path / "r"), "--runs-dir",
                           str(tmp_path / "runs")], capture_output=True, text=True)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert not any(tmp_path.iterdir())
