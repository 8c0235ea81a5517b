"""render: a GIF of one episode, for both environments; bad input is one line, exit 2, no file."""

from __future__ import annotations

import pytest
from PIL import Image


@pytest.mark.parametrize("env, policy", [("wildfire", "nearest"), ("bus", "nohold")])
def test_render_writes_an_animation(cli, tmp_path, env, policy):
    out = tmp_path / "episode.gif"
    res = cli("render", "--env", env, "--policy", policy, "--frames", "4", "--out", str(out))
    assert res.returncode == 0, res.stderr
    with Image.open(out) as gif:
        assert gif.n_frames >= 2 and gif.size[0] > 300
    assert [p.name for p in tmp_path.iterdir()] == ["episode.gif"]


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
