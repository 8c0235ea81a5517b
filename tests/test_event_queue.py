"""The shared event queue (repro.core.event_queue): SimPy's order, from arrays."""

from __future__ import annotations

import numpy as np

from repro.core.event_queue import (MAX_WHO, NORMAL, URGENT, event_key, heap_pop, heap_push,
                                    heap_replace_first, key_fields)


def test_keys_order_as_priority_then_sequence_and_carry_kind_and_who():
    assert event_key(URGENT, 9, 3, 5) < event_key(NORMAL, 1, 0, 0)
    assert event_key(NORMAL, 1, 15, MAX_WHO) < event_key(NORMAL, 2, 0, 0)
    assert key_fields(event_key(NORMAL, 123456789, 13, MAX_WHO)) == (123456789, 13, MAX_WHO)


def test_the_heap_gives_events_in_time_then_key_order():
    rng = np.random.default_rng(0)
    events = [(float(t), event_key(int(p), s, 0, s))
              for s, (t, p) in enumerate(zip(rng.integers(0, 5, 200), rng.integers(0, 2, 200)))]
    times, keys = np.empty(len(events)), np.empty(len(events), np.int64)
    for size, (t, k) in enumerate(events):
        heap_push(times, keys, size, t, k)
    got = [heap_pop(times, keys, size) for size in range(len(events), 0, -1)]
    assert got == sorted(events)


def test_replacing_the_first_is_a_pop_and_a_push():
    times, keys = np.empty(3), np.empty(3, np.int64)
    for size, t in enumerate((1.0, 2.0, 3.0)):
        heap_push(times, keys, size, t, event_key(NORMAL, size, 0, 0))
    heap_replace_first(times, keys, 3, 2.5, event_key(NORMAL, 3, 0, 0))
    assert [heap_pop(times, keys, size)[0] for size in (3, 2, 1)] == [2.0, 2.5, 3.0]
