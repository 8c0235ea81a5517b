"""A bad flag or value is refused before the heavy imports: reading and checking a command's
options imports neither torch nor matplotlib (seconds each on a loaded machine), only the run of a
command that needs them does. Checked by the modules imported, not by a clock, so that a loaded
machine cannot fail it."""

import json
import os
import subprocess
import sys

import pytest

from repro.cli import COMMANDS
from tests.conftest import ROOT

pytestmark = pytest.mark.slow  # a subprocess

HEAVY = ("torch", "matplotlib")

REFUSED = [[name, "--no-such-flag"] for name in COMMANDS] + [
    ["train", "--epoch", "2"],  # an abbreviation of --epochs
    ["train", "--env", "bus", "--gamma", "1e308", "--out", "run"],
    ["race", "--n-sets", "0"],
    ["transfer", "--seeds", "0"],
    ["claims", "--out", "x.csv"],
    ["wildfire-penalty", "--penalties", "-1"],
    ["bus-batch", "--sampler", "shared"],
    ["bus-eval", "--policy", "thresholds", "--thresholds", "-1", "-2", "-3"],
    ["bench-learn", "--epochs", "0"],
    ["plot-runs", "run", "--metric", "nonsense"],
]
"""Command lines each refused with exit status 2: a flag argparse does not know, or a value a
command's settings refuse."""

PROBE = """
import json, sys
from repro.cli import main
heavy, found = json.loads(sys.argv[1]), []
for argv in json.loads(sys.argv[2]):
    try:
        status = main(argv)
    except SystemExit as stop:
        status = stop.code
    found.append([argv, status, [m for m in heavy if m in sys.modules]])
    if found[-1][2]:
        break  # the next command lines would find it imported already
print(json.dumps(found))
"""


def test_bad_flags_and_values_are_refused_before_the_heavy_imports(tmp_path):
    env = dict(os.environ, REPRO_QUIET="1", PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", PROBE, json.dumps(HEAVY), json.dumps(REFUSED)],
                         cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    found = json.loads(out.stdout)
    for argv, status, imported in found:
        assert imported == [], f"{' '.join(argv)} imported {imported} before refusing"
        assert status == 2, f"{' '.join(argv)}: exit status {status}"
    assert len(found) == len(REFUSED)
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_the_probe_sees_a_heavy_import():
    """The check above can fail: with torch imported, the probe reports it."""
    env = dict(os.environ, REPRO_QUIET="1", PYTHONPATH=str(ROOT))
    script = PROBE.replace("from repro.cli import main", "from repro.cli import main\nimport torch")
    out = subprocess.run([sys.executable, "-c", script, json.dumps(HEAVY),
                          json.dumps([["race", "--no-such-flag"]])],
                         env=env, capture_output=True, text=True, timeout=600)
    assert json.loads(out.stdout)[0][2] == ["torch"]
