"""The gru policy pinned bit for bit: a short bus run of the authors' learner with ``--policy
gru`` (each Fisher-vector product), in the style of tests/test_learner_fingerprint.py and under
its skip rules. Its arithmetic is compiled float64 loops whose sums run in a fixed order
(repro.learn.gru_kernel), which give the same bits on every x86-64 CPU with AVX2 and FMA. The
digests were computed by this module (``python -m tests.test_gru_fingerprint``) on an Intel Xeon
(Emerald Rapids, AVX-512); they hold for the installed torch, numpy and numba."""

from __future__ import annotations

import hashlib

import repro  # noqa: F401  (first: run as a module, it pins the CPU kernels before numpy loads)

import numpy as np
import pytest

from repro.envs import env_package
from repro.learn.config import train_config
from repro.learn.process import configure_process
from repro.learn.trainer import Trainer
from repro.runs.run_folder import TIMING_COLUMNS
from tests.test_learner_fingerprint import not_pinned

RUN = dict(epochs=2, seed=7, batch_decisions=300, batch_workers=2, lam=2.0, policy="gru")
DIGESTS = {
    "finite-difference": "61a670ec3a7c30a2c75d9d1e8296be1f6050fad7d7d039068aa2bc7f4fd90732",
    "exact": "0122c9427d74d8ee202a8ac419857e84ba6bc6db6df54a24912cd87d2985658f",
}
"""Computed by the ``__main__`` block below (see the module docstring)."""


def fingerprint(fvp: str) -> str:
    """sha256 of a short gru run's progress table (without its timings) and final parameters."""
    pkg = env_package("bus")
    cfg = train_config("quick", "bus", **RUN, gru_fvp=fvp)
    configure_process()  # as the command line does
    trainer = Trainer(cfg, pkg.make_env(pkg.BusConfig()), env_config=pkg.BusConfig())
    frame = trainer.train().drop(columns=TIMING_COLUMNS)
    h = hashlib.sha256(frame.to_csv(index=False).encode())
    for tensor in trainer.policy.state_dict().values():
        h.update(tensor.numpy().tobytes())
    h.update(np.ascontiguousarray(trainer.baseline.state_dict()["coeffs"].numpy()).tobytes())
    return h.hexdigest()


@pytest.mark.skipif(bool(not_pinned()), reason=not_pinned() or "pinned")
@pytest.mark.parametrize("fvp", DIGESTS)
def test_the_gru_reproduces_its_recorded_runs(fvp):
    assert fingerprint(fvp) == DIGESTS[fvp]


if __name__ == "__main__":
    for name in DIGESTS:
        print(f'    "{name}": "{fingerprint(name)}",')
