import os
import subprocess
import sys
from pathlib import Path

import pytest

import repro  # noqa: F401  (first, so that it pins the CPU kernels before a test imports numpy)

ROOT = Path(__file__).resolve().parents[1]


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The tests that declare a longer time limit than the default (``pytest.mark.timeout``)
    run first, longest first, the others in their order: with a worker per core, a long test
    taken up last would keep one core busy while the others idle at the end of the run."""
    def limit(item: pytest.Item) -> float:
        mark = item.get_closest_marker("timeout")
        return float(mark.args[0]) if mark and mark.args else 0.0

    items.sort(key=lambda item: -limit(item))


def run_cli(*args: str, cwd: Path | None = None,
            timeout: float = 240) -> subprocess.CompletedProcess:
    """Run the real entry point, `python -m repro ...`, as a user would (killed after ``timeout``
    seconds, before pytest-timeout stops the test)."""
    env = dict(os.environ, REPRO_QUIET="1", PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "repro", *args], cwd=cwd or ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout)


def env_without_pins(**extra: str) -> dict[str, str]:
    """This process's environment without the variables that importing repro sets (so it holds
    the pinned values; repro.runs.kernels), plus ``extra``: what a fresh shell would hand a
    child process."""
    from repro.runs.kernels import NUMPY_VARIABLES, TORCH_PINS

    env = {k: v for k, v in os.environ.items() if k not in (*TORCH_PINS, *NUMPY_VARIABLES)}
    return {**env, "PYTHONPATH": str(ROOT), **extra}


def tree_snapshot(*dirs: Path) -> dict[str, bytes]:
    """Every file under ``dirs`` with its bytes (to prove that nothing was written)."""
    return {str(p): p.read_bytes() for d in dirs if d.exists() for p in sorted(d.rglob("*"))
            if p.is_file()}


@pytest.fixture
def cli():
    return run_cli


def write_result_csv(frame, path: Path, scale: str = "paper", **provenance) -> None:
    """A hand-made result CSV with the provenance sidecar every result has (claims read a CSV
    without one as missing); ``provenance``: more sidecar fields."""
    import json

    from repro.runs.results import sidecar_path

    frame.to_csv(path, index=False)
    sidecar_path(path).write_text(json.dumps({"scale": scale, **provenance}))


@pytest.fixture
def stored_intervals():
    """Claims decided with the CIs a test writes into its summaries (the drivers' percentile
    bootstrap, ``claims --interval percentile``) rather than t intervals from per-seed scores."""
    from repro.claims import intervals_of

    with intervals_of("percentile"):
        yield
