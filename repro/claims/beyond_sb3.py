"""X6, beyond the paper: does M-GAE, put into Stable-Baselines3's PPO (``repro.learn.sb3``), close
most of the gap between SB3's PPO with its own GAE and the suite's PS-TRPO with M-GAE?"""

from __future__ import annotations

from pathlib import Path

from repro.claims import Claim, Verdict, at_most_partial, scale_of
from repro.runs.results import read_provenance, read_result

MOST = 0.5
""""Most of the gap": M-GAE's share of it above this."""


def _num(x: float) -> str:
    return f"{x:.4g}" if abs(x) >= 100 else f"{x:.3f}"


def _pct(x: float) -> str:
    return f"{round(100 * x)}%"


def check_x6(results: Path) -> Verdict:
    """PASS when, in both environments, the bootstrap CI of the share of the gap that M-GAE closes
    lies above :data:`MOST`; FAIL when its point estimate is at most that in both; PARTIAL
    otherwise."""
    path = results / "beyond_sb3_summary.csv"
    s = read_result(path)
    parts, ours, holds, leans = [], [], [], []
    for env, grp in s.groupby("env", sort=False):
        g = grp.set_index("method")
        m = g.loc["sb3-ppo-mgae"]
        holds.append(m.gap_low > MOST)
        leans.append(m.gap_closed > MOST)
        cis = "; ".join(f"{r.method} {_num(r.mean)} [{_num(r.ci_low)}, {_num(r.ci_high)}]"
                        for r in grp.itertuples())
        parts.append(f"{env}: {cis}; M-GAE closes {_pct(m.gap_closed)} [{_pct(m.gap_low)}, "
                     f"{_pct(m.gap_high)}] of the gap from SB3's GAE to PS-TRPO")
        ours.append(f"{env}: {_pct(m.gap_closed)} of the gap closed")
    runs = read_result(results / "beyond_sb3.csv")
    for env, grp in runs[runs.method.str.startswith("sb3")].groupby("env", sort=False):
        last = grp.pivot(index="seed", columns="method", values="train_adr_last")
        if (last["sb3-ppo-gae"] == last["sb3-ppo-mgae"]).all():
            parts.append(f"On the {env}, SB3's PPO did not move its policy: its last training "
                         "batches are the same with either estimator, seed for seed")
    verdict = "PASS" if all(holds) else "FAIL" if not any(leans) else "PARTIAL"
    verdict, caveat = at_most_partial(verdict, int(s[s.method.str.startswith("sb3")].n_runs.min()))
    prov = read_provenance(path)
    cfg = prov["config"]
    kernels = "; ".join(", ".join(f"{k} {v}" for k, v in sorted(k.items()))
                        for k in prov.get("trained_under", []))
    detail = (f"{cfg['seeds']} runs per method, {cfg['updates']} updates of "
              f"{cfg['batch_decisions']:,} decisions each; test ADR on {cfg['test_episodes']:,} "
              "episodes per policy, mean [95% bootstrap CI] over runs (heuristic: one test, +-1.96 "
              "SEM over paths). " + ". ".join(parts) + ". PS-TRPO's runs are made under the "
              f"learner's arithmetic the sidecar records ({kernels}); SB3's do not use that "
              "learner: they compute with torch's own kernels, which may differ between CPU "
              "vendors in the last digits." + caveat)
    return Verdict("; ".join(ours), verdict, detail, scale_of(path))


CLAIMS = [
    Claim("X6", "Does M-GAE close most of the gap between Stable-Baselines3's PPO with its own "
          "per-decision GAE and PS-TRPO with M-GAE, at one budget (SB3's optimiser, clipping "
          "and minibatches unchanged)?", "M-GAE closes most of SB3's gap, in both environments",
          f"PASS: the share of the gap closed has its 95% bootstrap CI above {MOST:g} in both "
          f"environments; FAIL: its point estimate is at most {MOST:g} in both",
          "make beyond-sb3", check_x6, where="Sec. 3.2"),
]
