"""Pending events in arrays, ordered as SimPy orders them: the event queue the engines share.

SimPy processes events by the key (time, priority, insertion number): URGENT events (a process
starting, an interrupt) before NORMAL ones at the same time, then first scheduled, first processed
(docs/semantics.md section 2.4). Here an event is a time and one int64 key, priority << 62 |
sequence << 24 | kind << 20 | who (:func:`event_key`), so comparing keys compares (priority,
sequence) as SimPy does, as long as sequence numbers are unique among the pending events; kind
and who (an agent or another subject) ride along. The 38 bits of the sequence outlast any episode;
who must stay below 2^20 (:data:`MAX_WHO`).

The heap functions keep a binary min-heap of (time, key) pairs in two arrays; the caller keeps
its size (numba functions cannot change a scalar they are handed), so that the arrays may be
fields of an episode's record. With unique keys the order is total: any correct heap processes
the same events in the same order.

Who uses what, and why:

- the wildfire engine: this heap, plus two FIFO queues of the events due now (URGENT and NORMAL)
  that never enter the heap. In the released same-instant order most events are zero-delay steps
  (a sub-process starting or ending, an AnyOf triggering), so the queues save a sift per event
  (``repro/envs/wildfire/engine.py``, ``_push``).
- the renewal simulators: this heap alone, one pending event per agent, keyed by its scheduling
  number (SimPy's order) or by the agent's index.
- the bus engine: not this heap but an array kept sorted by insertion (``_schedule`` in
  ``repro/envs/bus/engine.py``). At most 2 N (12) events are pending and a new event has the
  largest insertion number, so it is placed by shifting the few events that come later, and
  neither priority nor sequence need be stored; the next event is the array's last entry. With
  this heap instead (six alternating runs of ``bench-bus`` each) the engine
  made 3-4% fewer decisions per CPU second with the learner's policy, in ``rollout`` and the step
  API, and 3% more with No Holding: training's case decides.
"""

from __future__ import annotations

import numpy as np
from numba import njit

URGENT, NORMAL = 0, 1
"""SimPy's priorities: an interrupt or a process start at time t comes before any timeout at t."""
WHO_BITS, KIND_BITS, PRIO_SHIFT = 20, 4, 62
"""Bits of an event key's who and kind, and where its priority starts."""
SEQ_SHIFT = WHO_BITS + KIND_BITS
MAX_WHO = (1 << WHO_BITS) - 1
"""The largest subject (agent or fire index) a key holds."""


@njit(cache=True)
def event_key(priority, seq, kind, who):
    """The key of an event: orders as (priority, seq); carries kind (< 16) and who (<= MAX_WHO)."""
    return ((np.int64(priority) << PRIO_SHIFT) | (np.int64(seq) << SEQ_SHIFT)
            | (np.int64(kind) << WHO_BITS) | np.int64(who))


@njit(cache=True)
def key_fields(key):
    """(sequence, kind, who) of an event key."""
    who = key & MAX_WHO
    kind = (key >> WHO_BITS) & ((1 << KIND_BITS) - 1)
    seq = (key >> SEQ_SHIFT) & ((np.int64(1) << (PRIO_SHIFT - SEQ_SHIFT)) - 1)
    return seq, kind, who


@njit(cache=True)
def heap_push(times, keys, size, time, key):
    """Add (time, key) to the heap of ``size`` entries (it then has size + 1)."""
    hole = size
    while hole > 0:  # sift the new entry up, moving parents into the hole
        parent = (hole - 1) // 2
        parent_time = times[parent]
        if parent_time < time or (parent_time == time and keys[parent] < key):
            break
        times[hole] = parent_time
        keys[hole] = keys[parent]
        hole = parent
    times[hole] = time
    keys[hole] = key


@njit(cache=True)
def heap_pop(times, keys, size):
    """Remove the first (time, key) of the heap of ``size`` >= 1 entries and return it (the heap
    then has size - 1)."""
    first = times[0], keys[0]
    _sift_down(times, keys, size - 1, times[size - 1], keys[size - 1])
    return first


@njit(cache=True)
def heap_replace_first(times, keys, size, time, key):
    """Replace the first entry of the heap of ``size`` >= 1 entries by (time, key): a pop and a
    push in one sift."""
    _sift_down(times, keys, size, time, key)


@njit(cache=True)
def _sift_down(times, keys, size, time, key):
    """Place (time, key) in the hole at the root of the first ``size`` entries, sifting down."""
    hole = 0
    while True:
        child = 2 * hole + 1
        if child >= size:
            break
        if child + 1 < size and (times[child + 1] < times[child] or (
                times[child + 1] == times[child] and keys[child + 1] < keys[child])):
            child += 1
        if time < times[child] or (time == times[child] and key < keys[child]):
            break
        times[hole] = times[child]
        keys[hole] = keys[child]
        hole = child
    times[hole] = time
    keys[hole] = key
