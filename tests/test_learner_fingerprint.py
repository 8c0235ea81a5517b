"""Both learners pinned bit for bit: a short run of each, in the bytes it gives on every x86-64
CPU with AVX2 and FMA, of any vendor (the learner's arithmetic is compiled loops in a fixed order:
repro.runs.kernels; tests/test_kernel_levels.py). The digests were computed by this module
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

from repro.runs import kernels
from repro.envs import env_package
from repro.learn.config import train_config
from repro.learn.process import configure_process
from repro.learn.trainer import Trainer
from repro.runs.run_folder import TIMING_COLUMNS

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
        "wildfire ED": "43d3f7839004339751b87908e5495e983b99a16c387a5e83293e40444ef31740",
        "wildfire FS-1": "10e50b06b122d77fbcd2cb0cb5b69dc36f263e44540e3680e24cf99b966dee64",
        "bus": "776241dc80b90454a2d8d933cf738fc0e6be1ff9f40ca769bec876c7bd03d5a9",
    },
    "authors": {
        "wildfire ED": "bc258411f299262d0399fbb676ae69e2ed65e99652497b5f49633cf8504e4578",
        "wildfire FS-1": "677c52671e8520929c6af9b8f621c765735bef1e2a271403d0a1913e5815343b",
        "bus": "b11b77540f9bd3d493ada7907f20b65e32671b1a28ffadef25fb9b06e413ccca",
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
