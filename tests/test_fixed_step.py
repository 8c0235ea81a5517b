"""The one FS-dT rounding rule (repro.core.fixed_step), at its edges."""

from __future__ import annotations

import pytest

from repro.core.fixed_step import fs_delay, fs_step, fs_time


def test_an_event_is_rounded_up_to_the_next_grid_point():
    assert fs_step(0.0, 0.3, 0.25) == 2.0
    assert fs_time(0.0, 0.3, 0.25) == 0.5
    assert fs_delay(0.1, 0.3, 0.25) == pytest.approx(0.4, abs=1e-15)
    # the mechanism of C9: an attack started one latency after a grid point
    assert fs_delay(1e-5, 3.0, 1.0) + 1e-5 == pytest.approx(4.0, abs=1e-12)
    assert fs_delay(1e-5, 2.9999, 1.0) + 1e-5 == pytest.approx(3.0, abs=1e-12)


def test_an_exact_multiple_stays_where_it_is():
    assert fs_step(2.0, 1.0, 1.0) == 3.0
    assert fs_time(2.0, 1.0, 1.0) == 3.0
    assert fs_delay(2.0, 1.0, 1.0) == 1.0
    assert fs_delay(3.0, 0.0, 1.0) == 0.0  # a zero delay on the grid: now


def test_ed_does_not_round():
    assert fs_time(0.5, 0.25, 0.0) == 0.75
    assert fs_delay(0.5, 0.25, 0.0) == 0.25
    assert fs_delay(0.5, -0.1, 0.0) == 0.0


@pytest.mark.parametrize("now, delay, dt", [(100.0, 3.0, 1e-17), (0.5, 2.0, 1e-300)])
def test_huge_step_counts_do_not_overflow(now, delay, dt):
    """An int64 ceiling (numba's math.ceil) wrapped past 2^63 steps, to a delay of 0."""
    assert fs_step(now, delay, dt) > 2.0 ** 63
    assert fs_time(now, delay, dt) >= now + delay
    assert fs_delay(now, delay, dt) >= delay - 1e-9


def test_negative_delays_round_like_any_or_count_as_zero():
    # rounded like any (the released code): a grid point between the run-out (0.9) and now (1.2)
    # is in the past, so at once; none between them (run-out 1.1): the next one
    assert fs_delay(1.2, -0.3, 1.0) == 0.0
    assert fs_delay(1.2, -0.1, 1.0) == pytest.approx(0.8, abs=1e-15)
    # counted as 0 first: the next grid point, or now on one
    assert fs_delay(1.2, -0.3, 1.0, False) == pytest.approx(0.8, abs=1e-15)
    assert fs_delay(2.0, -0.5, 1.0, False) == 0.0
