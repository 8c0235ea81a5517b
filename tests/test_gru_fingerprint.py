"""The gru policy pinned bit for bit: a short bus run of the authors' learner with ``--policy
gru`` (each Fisher-vector product), in the style of tests/test_learner_fingerprint.py and under
its skip rules. Its arithmetic is torch in float64 (repro.learn.gru): matrix products in MKL at
``MKL_CBWR=COMPATIBLE``, MKL's documented cross-vendor branch, elementwise kernels at AVX2. The
digests were computed by this module (``python -m tests.test_gru_fingerprint``) on an AMD EPYC
(Zen 5, AVX-512); they hold for the installed torch, numpy and numba."""

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
    "finite-difference": "45d838ee12dd7b3295636713693ba8ffb6a6962a4b51bc370195ff4a6b0504a3",
    "exact": "39347c0e9cf772398dd8366e0e90cc026f1d262591292eba29982c0f22f81d4b",
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
