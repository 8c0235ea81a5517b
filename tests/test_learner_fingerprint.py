"""The suite's learner kept bit for bit: ``--learner suite`` trains exactly the runs it trained
before the authors' learner became the default (the digests were computed by this module,
``python -m tests.test_learner_fingerprint``, on the code of commit 9d3bbb2, before the learner
settings existed). Exact-bit digests: they hold on this machine's torch, numpy and numba builds."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from repro.envs import env_package
from repro.learn.config import train_config
from repro.learn.trainer import TIMING_COLUMNS, Trainer

RUNS = {  # name: (env, train overrides, env config fields)
    "wildfire ED": ("wildfire", dict(epochs=3, batch_episodes=12, seed=5), dict()),
    "wildfire FS-1": ("wildfire", dict(epochs=3, batch_episodes=12, seed=6), dict(dt=1.0)),
    "bus": ("bus", dict(epochs=2, batch_episodes=3, seed=7), dict()),
}
DIGESTS = {
    "wildfire ED": "435629193b35e29e94fdc1ac2d9137f7f604f15781fded1efd3ada78bf7bdf68",
    "wildfire FS-1": "213413d221810c926790519c1fe6557baf71092faaf6e1354789a8c61ca1d7c7",
    "bus": "fa8d7d0bbba47bdc9ce9ab37b047c45e1948e1aa40bb08026eaf96f12e4ed2e4",
}
"""Computed on commit 9d3bbb2 by the ``__main__`` block below."""


def fingerprint(name: str, **learner) -> str:
    """sha256 of a short run's progress table (without its timings) and final parameters."""
    env_name, overrides, env_fields = RUNS[name]
    pkg = env_package(env_name)
    env_cfg = (pkg.WildfireConfig if env_name == "wildfire" else pkg.BusConfig)(**env_fields)
    cfg = train_config("quick", env_name, **learner, **overrides)
    trainer = Trainer(cfg, pkg.make_env(env_cfg), env_config=env_cfg)
    frame = trainer.train().drop(columns=TIMING_COLUMNS)
    h = hashlib.sha256(frame.to_csv(index=False).encode())
    for tensor in trainer.policy.state_dict().values():
        h.update(tensor.numpy().tobytes())
    for array in (trainer.normalizer.mean, trainer.normalizer.var):
        h.update(np.ascontiguousarray(array).tobytes())
    return h.hexdigest()


@pytest.mark.parametrize("name", RUNS)
def test_suite_learner_reproduces_recorded_runs(name):
    assert fingerprint(name, learner="suite") == DIGESTS[name]


if __name__ == "__main__":
    import sys

    kwargs = dict(learner=sys.argv[1]) if len(sys.argv) > 1 else {}
    for n in RUNS:
        print(f'    "{n}": "{fingerprint(n, **kwargs)}",')
