"""``train --tensorboard DIR``: each epoch's progress row as TensorBoard scalars, read back with
tensorboard's own reader; without the package, one line naming the option and the pip command,
exit status 2, nothing written."""

from __future__ import annotations

import sys

import pandas as pd
import pytest

from repro.cli import main
from repro.runs.run_folder import PROGRESS_COLUMNS
from tests.conftest import tree_snapshot

TRAIN = ["train", "--env", "toy", "--scale", "smoke", "--batch-episodes", "4", "--seed", "2",
         "--horizon", "10"]


def scalars(folder) -> dict[str, list[tuple[int, float]]]:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(str(folder))
    events.Reload()
    return {tag: [(e.step, e.value) for e in events.Scalars(tag)]
            for tag in events.Tags()["scalars"]}


def test_progress_rows_are_logged_as_scalars(tmp_path):
    pytest.importorskip("tensorboard")
    run, board = tmp_path / "run", tmp_path / "board"
    assert main([*TRAIN, "--epochs", "2", "--out", str(run), "--tensorboard", str(board)]) == 0
    progress = pd.read_csv(run / "progress.csv")
    logged = scalars(board)
    assert sorted(logged) == sorted(c for c in PROGRESS_COLUMNS if c != "epoch")
    for column, points in logged.items():
        assert [s for s, _ in points] == list(progress.epoch), column
        assert [v for _, v in points] == pytest.approx(list(progress[column]), rel=1e-6), column
    # a resumed run logs the epochs it trains
    assert main([*TRAIN, "--epochs", "3", "--out", str(run), "--tensorboard", str(board)]) == 0
    assert [s for s, _ in scalars(board)["average_return"]] == [0, 1, 2]


def test_without_the_package_it_is_one_line_and_nothing_is_written(tmp_path, monkeypatch,
                                                                     capsys):
    monkeypatch.setitem(sys.modules, "torch.utils.tensorboard", None)  # import fails
    before = tree_snapshot(tmp_path)
    code = main([*TRAIN, "--epochs", "1", "--out", str(tmp_path / "run"),
                 "--tensorboard", str(tmp_path / "board")])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "--tensorboard" in err and "pip install tensorboard" in err
    assert tree_snapshot(tmp_path) == before and not list(tmp_path.iterdir())
