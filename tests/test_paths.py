"""Decisions packed into paths (repro.core.paths), the layout of every engine's rollout."""

from __future__ import annotations

import numpy as np
import pytest

from repro.core.paths import path_layout, path_order


def test_layout_is_episode_major():
    start, episode, agent = path_layout(np.array([[2, 0, 1], [1, 3, 0]], np.int32))
    assert start.tolist() == [0, 2, 2, 3, 4, 7, 7]
    assert episode.tolist() == [0, 0, 0, 1, 1, 1]
    assert agent.tolist() == [0, 1, 2, 0, 1, 2]
    assert start.dtype == episode.dtype == agent.dtype == np.int64


def test_interleaved_rows_go_to_their_places():
    # rows as they happen: two agents of one episode, one of another, interleaved
    episode = np.array([1, 0, 0, 1, 0, 0])
    agent = np.array([0, 1, 0, 0, 1, 1])
    index = np.array([0, 0, 0, 1, 1, 2])
    start, _, _ = path_layout(np.array([[1, 3], [2, 0]]))
    order = path_order(episode, agent, index, 2, start)
    assert order.tolist() == [2, 1, 4, 5, 0, 3]
    assert np.array_equal(index[order], [0, 0, 1, 2, 0, 1])


@pytest.mark.parametrize("index", [[0, 0, 1], [0, 1, 3], [0, -1, 1]])
def test_numbers_that_are_not_0_1_each_once_are_refused(index):
    start, _, _ = path_layout(np.array([[3]]))
    with pytest.raises(ValueError, match="numbered"):
        path_order(np.zeros(3, np.int64), np.zeros(3, np.int64), np.array(index), 1, start)


def test_rows_that_do_not_fill_the_paths_are_refused():
    start, _, _ = path_layout(np.array([[3]]))
    with pytest.raises(ValueError, match="fill"):
        path_order(np.zeros(2, np.int64), np.zeros(2, np.int64), np.arange(2), 1, start)
