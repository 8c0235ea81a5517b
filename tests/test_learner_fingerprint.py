"""Both learners pinned bit for bit: a short run of each, in the bytes it gives on every x86-64
CPU with AVX2 and FMA, of any vendor (the learner's arithmetic is compiled loops in a fixed order:
repro.core.kernels; tests/test_kernel_levels.py). The digests were computed by this module
(``python -m tests.test_learner_fingerprint [authors]``) on an AMD EPYC (Zen 5, AVX-512), and were
the same there with numba compiling for a generic x86-64, for Haswell and for the host, with and
without the pin. They hold for the installed torch, numpy and numba and glibc's libm. Where the pin
does not apply (another architecture, no AVX2 or FMA, ``REPRO_NATIVE_KERNELS=1``) or did not take,
the tests skip, saying why."""

from __future__ import annotations

import hashlib

import repro  # noqa: F401  (first: run as a module, it pins the CPU kernels before numpy loads)

import numpy as np
import pytest

from repro.core import kernels
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
        "wildfire ED": "29ff09df5d3d19ef45dc7be3cecee749f9a70871a97b853ae4bedc1078c5ea8d",
        "wildfire FS-1": "ba07b78975b3930cfb807faf0b5f73870b9289821e09594f50afa9361699dd07",
        "bus": "0091a0d5995f3c80aba7d06f6df204cba4ff67c7d9f48bfc9ecbf0ea9a01bce4",
    },
    "authors": {
        "wildfire ED": "2a540ad2b87b1171e45241d5e0212522f0f0de50b3075b97813bc2427684286f",
        "wildfire FS-1": "0ea6b11784e451d87d21d36433583e4f2f58672acbf0677722228a69a2e27dcd",
        "bus": "6cfd05b74fedc1e5dfb618fb3855f7a88e226b40afa49b2414fac1b615627bc9",
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


def not_pinned() -> str:
    """Why the digests do not apply to this process ('' where they do)."""
    if not kernels.pinnable():
        return "the pin applies to x86-64 CPUs with AVX2 and FMA (and no REPRO_NATIVE_KERNELS)"
    return "; ".join(kernels.problems())


@pytest.mark.skipif(bool(not_pinned()), reason=not_pinned() or "pinned")
@pytest.mark.parametrize("learner", DIGESTS)
@pytest.mark.parametrize("name", RUNS)
def test_each_learner_reproduces_its_recorded_runs(name, learner):
    assert fingerprint(name, learner) == DIGESTS[learner][name]


if __name__ == "__main__":
    import sys

    for n in RUNS:
        print(f'        "{n}": "{fingerprint(n, sys.argv[1] if len(sys.argv) > 1 else "suite")}",')
