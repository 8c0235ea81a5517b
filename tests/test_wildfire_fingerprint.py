"""Today's semantics kept bit for bit: with every same-instant switch at its pre-issue-18 setting,
both engines reproduce the rollouts recorded before the released semantics were added.

The digests were computed by this module (``python -m tests.test_wildfire_fingerprint``) on the
code of commit 2315184; they are exact-bit digests, so they hold on this machine's numpy/numba
builds (another libm may change a last bit of exp or sqrt and fail them).
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from repro.envs.wildfire import WildfireConfig, make_env, make_reference_env
from repro.envs.wildfire.policies import POLICIES

BEFORE = dict(quirk_q3_unclamped_health=False, quirk_q4_latency_not_interrupted=False,
              quirk_q5_discount_from_action_start=False, same_instant_order="scheduling",
              ranking_resolution=0.0, fs_round_negative_delays=False,
              cut_flight_continues=False, quirk_q6_short_flight_stays=False)
"""The switches' settings that give the semantics of before issue 18."""
CONFIGS = {  # name: (policy, config)
    "ED random": ("random", dict()),
    "FS-1 random": ("random", dict(dt=1.0)),
    "FS-10 random": ("random", dict(dt=10.0)),
    "ED flowchart": ("flowchart", dict()),
    "FS-1 flowchart": ("flowchart", dict(dt=1.0)),
    "FS-1 health 2.9999 flowchart": ("flowchart", dict(dt=1.0, t_health=2.9999)),
    "corrected FS-0.316 flowchart": ("flowchart", dict(dt=10 ** -0.5, quirk_q1_stale_attack=False,
                                                       quirk_q2_penalty_party_only=False)),
}
ENGINES = {"reference": make_reference_env, "fast": make_env}
EPISODES, SEED = 6, 2024
DIGESTS = {
    "reference ED random":
        "ddfc1b370f4753211d0822e070774ba5b1a502790fbe0497ca9876e763df9cdb",
    "reference FS-1 random":
        "1eec061f3dceaefb4d5c50a147cd043d9ab934795ead1fd74c61b97bcc1d9576",
    "reference FS-10 random":
        "baab6f492d50aac260ec42af1c83801d33eadf46d097f1e543a462f2c65cb288",
    "reference ED flowchart":
        "099871cf8ab461509ad9093d4c997a420b59b4d14517e8eb510b299b4ec4feb7",
    "reference FS-1 flowchart":
        "637ffc9b74456b0e687438d55f6c08372a2944629ffe210bae2f208b9aba551c",
    "reference FS-1 health 2.9999 flowchart":
        "1d9861016125cf20d331aa9d0ab943261c1f1328f8df0f0c2ef8a1760e06cceb",
    "reference corrected FS-0.316 flowchart":
        "e5bf5fcd8b08d9c1b388d151f2804f166e29f3d9549c64192ad030a48f42a7df",
    "fast ED random":
        "6f127326b1276da56b7244fc09c5325d28a32ffe7b189943a9adcb88cb43461a",
    "fast FS-1 random":
        "f37416f6e4a67a2c50e6940a7a718fe5084a9caab53b0a8e9ee6a275f3f9df80",
    "fast FS-10 random":
        "5e21b44a72ffe1fa704fff1b91278c77c766e4771ae437761d7e32def5567e22",
    "fast ED flowchart":
        "f69a4e75eaa4cddb0c4e088bd1e5c4317ed07b264a6772c61c73cb9717bcd664",
    "fast FS-1 flowchart":
        "6c4f1afe73f4748cf6cb52cdee9b6c75f5c94f157187ea4382a6babc6cb4e3fd",
    "fast FS-1 health 2.9999 flowchart":
        "8158ff16ad8fde0e8e369b2dde701902e58e5908f5be3efc9dc40d3eafcaba28",
    "fast corrected FS-0.316 flowchart":
        "7221e166ab41c0e9bcd478f7f59ea58d9cdcc9a4b6c5fd26d197f7b50ab7eca5",
}
"""Computed on commit 2315184 (before issue 18), by the ``__main__`` block below."""


def fingerprint(engine: str, name: str) -> str:
    """sha256 of one rollout's arrays (a fixed seed)."""
    kind, kwargs = CONFIGS[name]
    cfg = WildfireConfig(**kwargs, **BEFORE)
    policy = POLICIES[kind](np.random.default_rng(SEED), n_observed=cfg.n_observed)
    r = ENGINES[engine](cfg).rollout(policy, EPISODES, SEED)
    h = hashlib.sha256()
    for a in (r.obs, r.actions, r.rewards, r.durations, r.path_start, r.episode_return,
              r.info["decision_time"], r.info["end_time"]):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("name", CONFIGS)
def test_before_issue_18_switches_reproduce_recorded_rollouts(engine, name):
    assert fingerprint(engine, name) == DIGESTS[f"{engine} {name}"]


if __name__ == "__main__":
    for e in ENGINES:
        for n in CONFIGS:
            print(f'    "{e} {n}":\n        "{fingerprint(e, n)}",')
