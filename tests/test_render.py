"""render: a GIF of one episode, for both environments, with a sidecar naming what it pictures; bad
input is one line, exit 2, no file."""

from __future__ import annotations

import hashlib
import json

import pytest
from PIL import Image

pytestmark = pytest.mark.slow  # studies end to end, subprocesses: left out of make test-fast


@pytest.mark.parametrize("env, policy", [("wildfire", "nearest"), ("bus", "nohold")])
def test_render_writes_an_animation(cli, tmp_path, env, policy):
    out = tmp_path / "episode.gif"
    res = cli("render", "--env", env, "--policy", policy, "--frames", "4", "--out", str(out))
    assert res.returncode == 0, res.stderr
    with Image.open(out) as gif:
        assert gif.n_frames >= 2 and gif.size[0] > 300
    assert sorted(p.name for p in tmp_path.iterdir()) == ["episode.gif",
                                                         "episode.provenance.json"]
    side = json.loads((tmp_path / "episode.provenance.json").read_text())
    assert side["figures"] == {"episode.gif": hashlib.sha256(out.read_bytes()).hexdigest()}
    assert side["policy"] == policy and "--frames" in side["argv"] and side["git_commit"]


def test_the_sidecar_names_the_checkpoint_it_pictures(cli, tmp_path):
    run = tmp_path / "run"
    assert cli("train", "--env", "wildfire", "--scale", "smoke", "--epochs", "1",
               "--out", str(run)).returncode == 0
    out = tmp_path / "episode.gif"
    checkpoint = run / "checkpoint.pt"
    res = cli("render", "--policy", "checkpoint", str(checkpoint), "--frames", "3",
              "--out", str(out))
    assert res.returncode == 0, res.stderr
    side = json.loads((tmp_path / "episode.provenance.json").read_text())
    assert side["policy_file"] == {"path": str(checkpoint), "sha256": hashlib.sha256(
        checkpoint.read_bytes()).hexdigest()}


@pytest.mark.parametrize("args, param", [
    (("--env", "sea"), "--env"),
    (("--policy", "nohold"), "--policy"),  # a bus policy for the wildfire
    (("--policy", "checkpoint"), "--policy"),  # without its path
    (("--policy", "random", "extra"), "--policy"),
    (("--policy", "checkpoint", "missing.pt"), "--policy"),
    (("--frames", "1"), "--frames"),
    (("--out", "episode.png"), "--out"),
    (("--out", "no/such/folder/episode.gif"), "--out"),
])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(cli, tmp_path, args, param):
    full = ["render", "--out", str(tmp_path / "episode.gif"), *args]
    if "--out" in args:
        full = ["render", *args[:-1], str(tmp_path / args[-1])]
    res = cli(*full)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and param in lines[0], res.stderr
    assert not list(tmp_path.iterdir())
