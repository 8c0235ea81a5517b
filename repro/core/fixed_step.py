"""Fixed-step (FS-dT) rounding, the one rule every engine uses (docs/semantics.md section 2.3).

An event scheduled at ``now`` with delay d happens, in FS-dT, at the first point of the dT grid at
or after now + d: step k = ceil((now + d) / dT), time k dT. ``dt <= 0`` stands for ED (no
rounding). Three views of that one rule, for the three kinds of simulator:

- :func:`fs_step`, the step k, for a simulator that counts steps (the time-stepped one);
- :func:`fs_time`, the time k dT, for one that keeps event times;
- :func:`fs_delay`, the delay k dT - now, for one that schedules by delay as SimPy does (its
  event then happens at now + (k dT - now), which may differ from k dT in the last bit, so the
  engines that mirror a SimPy model use this view).

The step is a float ceiling: numba's ``math.ceil`` returns an int64, which overflows (to a delay
of 0, or a step in the past) once the number of steps passes 2^63, as it does for a tiny dT. The
functions are compiled; Python code calls them as they are (the SimPy models do).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def fs_step(now: float, delay: float, dt: float) -> float:
    """The grid step k = ceil((now + delay) / dt) (dt > 0) at which the event happens, as a float
    (integer-valued, never overflows)."""
    return np.ceil((now + delay) / dt)


@njit(cache=True)
def fs_time(now: float, delay: float, dt: float) -> float:
    """The time at which an event scheduled at ``now`` after ``delay`` happens: now + delay in ED
    (dt <= 0), else rounded up to the grid."""
    if dt <= 0.0:
        return now + delay
    return fs_step(now, delay, dt) * dt


@njit(cache=True)
def fs_delay(now: float, delay: float, dt: float, round_negative: bool = True) -> float:
    """The delay that replaces ``delay`` scheduled at ``now``: its end rounded up to the grid, and
    at least 0.

    A negative delay (the wildfire: a fire whose health ran out before its rounded extinguish
    event, re-planned at a party change) is rounded like any other if ``round_negative``
    (docs/semantics.md section 3.11, the released code: to the grid point at or before now when
    that is after now + delay, so at once), else it first counts as 0 (rounded up to the next grid
    point, or now on it).
    """
    d = delay if round_negative else max(delay, 0.0)
    if dt <= 0.0:
        return max(d, 0.0)
    return max(0.0, fs_time(now, d, dt) - now)
