"""Both learners pinned bit for bit. ``--learner suite`` trains exactly the runs it trained before
the authors' learner became the default (its digests were computed by this module, ``python -m
tests.test_learner_fingerprint``, on the code of commit 9d3bbb2, before the learner settings
existed); the authors' learner, the default, trains the runs it trained when its paper-scale
results were made (``python -m tests.test_learner_fingerprint authors`` gives the same digests at
commit e6b44d1, which trained the first of them, as at HEAD).
Exact-bit digests: they hold on this machine's torch, numpy and numba builds."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from repro.envs import env_package
from repro.learn.config import train_config
from repro.learn.process import configure_process
from repro.learn.trainer import TIMING_COLUMNS, Trainer

RUNS = {  # name: (env, train overrides, env config fields)
    "wildfire ED": ("wildfire", dict(epochs=3, seed=5), dict()),
    "wildfire FS-1": ("wildfire", dict(epochs=3, seed=6), dict(dt=1.0)),
    "bus": ("bus", dict(epochs=2, seed=7), dict()),
}
BATCH = {  # learner: batch size of every run, in its unit
    "suite": {"wildfire": dict(batch_episodes=12), "bus": dict(batch_episodes=3)},
    "authors": {"wildfire": dict(batch_decisions=400, batch_workers=4),
                "bus": dict(batch_decisions=400, batch_workers=2)},
}
DIGESTS = {
    "suite": {
        "wildfire ED": "435629193b35e29e94fdc1ac2d9137f7f604f15781fded1efd3ada78bf7bdf68",
        "wildfire FS-1": "213413d221810c926790519c1fe6557baf71092faaf6e1354789a8c61ca1d7c7",
        "bus": "fa8d7d0bbba47bdc9ce9ab37b047c45e1948e1aa40bb08026eaf96f12e4ed2e4",
    },
    "authors": {
        "wildfire ED": "13e5bb492737b90b755bf837e7bc91507850ce4cdee52aafb23cb20da048bdee",
        "wildfire FS-1": "707d088dd3bdbc077feef697c01f8e5ea6268225b53ca407f3bd574826cc1a82",
        "bus": "48d5475c7a7b0b69f475ed20d104a158720f782c4b78cb8cff9fd4aa36815c8e",
    },
}
"""Computed by the ``__main__`` block below, at the commits the module docstring names."""


def fingerprint(name: str, learner: str) -> str:
    """sha256 of a short run's progress table (without its timings) and final parameters."""
    env_name, overrides, env_fields = RUNS[name]
    pkg = env_package(env_name)
    env_cfg = (pkg.WildfireConfig if env_name == "wildfire" else pkg.BusConfig)(**env_fields)
    cfg = train_config("quick", env_name, learner, **overrides, **BATCH[learner][env_name])
    configure_process()  # as the command line does
    trainer = Trainer(cfg, pkg.make_env(env_cfg), env_config=env_cfg)
    frame = trainer.train().drop(columns=TIMING_COLUMNS)
    h = hashlib.sha256(frame.to_csv(index=False).encode())
    for tensor in trainer.policy.state_dict().values():
        h.update(tensor.numpy().tobytes())
    for array in (trainer.normalizer.mean, trainer.normalizer.var):
        h.update(np.ascontiguousarray(array).tobytes())
    return h.hexdigest()


@pytest.mark.parametrize("learner", DIGESTS)
@pytest.mark.parametrize("name", RUNS)
def test_each_learner_reproduces_its_recorded_runs(name, learner):
    assert fingerprint(name, learner) == DIGESTS[learner][name]


if __name__ == "__main__":
    import sys

    for n in RUNS:
        print(f'        "{n}": "{fingerprint(n, sys.argv[1] if len(sys.argv) > 1 else "suite")}",')
