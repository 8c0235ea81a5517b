"""Both learners pinned bit for bit: a short run of each, in the bytes it gives on every x86-64
CPU with AVX2 (the CPU kernels are pinned: repro.runs.kernels; tests/test_kernel_levels.py). The
digests were computed by this module (``python -m tests.test_learner_fingerprint [authors]``) on
the code that pinned the kernels; on this project's AVX-512 machine they differ in the last bits
from the unpinned code's (CHANGELOG.md, 2026-11-26). They hold for the installed torch, numpy and
numba; a 3-epoch run gave the same bytes under torch 2.11 and numpy 2.5 on another machine."""

from __future__ import annotations

import hashlib

import repro  # noqa: F401  (first: run as a module, it pins the CPU kernels before numpy loads)

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
        "wildfire ED": "66fb2cdb97c048aa23de12ed55548734834e80e4d983a29f372ae1d871799516",
        "wildfire FS-1": "62fc03b83585d02fd25c9144a8dd83b6ccfe7b8cdc1815a74828e2c51075f27e",
        "bus": "62eb1bdca43d9be914e95370148c6ef13d16b44be27e1617e663be80fb1db097",
    },
    "authors": {
        "wildfire ED": "61ff888ede3c2fb52ea15ecc612426c99663da5903e0a5f24beb77a8be397366",
        "wildfire FS-1": "563afcac7a8b6cfac83d10604b88dd82070a47fb2a18251a9d295733db23394f",
        "bus": "2983133a3ee09cb407d31b96d96c14a625d5b8cbb5d32e1c652266ebf7c0e04a",
    },
}
"""Computed by the ``__main__`` block below (see the module docstring)."""


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
