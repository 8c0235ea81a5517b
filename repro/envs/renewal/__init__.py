"""A generic N-agent renewal event process, simulated three ways (claim C11, docs/semantics.md
section 6.7).

Not an environment of the paper: it is the abstract process behind the paper's scaling argument
("event times drawn from p(t)"), used to measure what event-driven and time-stepped simulation cost.
"""

from repro.envs.renewal.engine import (
    TIE_AGENT,
    TIE_SCHEDULED,
    TIE_ORDERS,
    Outcome,
    StreamDraws,
    draw_inter_event_times,
    simulate_events,
    simulate_steps,
)

__all__ = ["TIE_AGENT", "TIE_SCHEDULED", "TIE_ORDERS", "Outcome", "StreamDraws",
           "draw_inter_event_times", "simulate_events", "simulate_steps"]
