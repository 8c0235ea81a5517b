"""Pictures of a bus episode: the loop corridor with its stops, every bus where it is, and its
load, from the fast engine's state, drawn with matplotlib."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from repro.envs.bus.engine import TRAVEL
from repro.envs.bus.params import BusConfig


@dataclass(frozen=True)
class Frame:
    """The corridor at one instant."""

    time: float
    """Simulation time (s)."""
    position: np.ndarray
    """(N,) where each bus is, in stops along the loop: k at (or queueing for) stop k, k + f on
    its way from stop k to the next, f the part of the trip done."""
    load: np.ndarray
    """(N,) passengers on board."""


def frame_of_state(cfg: BusConfig, state: np.void) -> Frame:
    """The frame of one episode's state record of the fast engine (see ``BusBatch.state``)."""
    now = float(state["now"])
    position = state["stop"].astype(float)
    n_ev = int(state["n_ev"])
    for kind, bus, t in zip(state["ev_kind"][:n_ev], state["ev_arg"][:n_ev],
                            state["ev_time"][:n_ev]):
        if kind == TRAVEL:  # on the way to the next stop, due at t
            position[bus] += 1.0 - (t - now) / cfg.travel_time
    return Frame(time=now, position=position, load=state["load"].astype(np.int64))


def draw(fig, frame: Frame, cfg: BusConfig) -> None:
    """Draw ``frame`` on the matplotlib figure ``fig`` (cleared first): the stops on a circle
    (the loop, run anticlockwise), each bus a coloured dot on it, labelled with its load, and the
    loads as bars against the capacity."""
    fig.clear()
    ax, bars = fig.subplots(1, 2, gridspec_kw={"width_ratios": [3, 2]})
    k, n = cfg.n_stops, len(frame.load)

    def angle(pos: np.ndarray) -> np.ndarray:
        return np.pi / 2 + 2 * np.pi * np.asarray(pos) / k

    ring = np.linspace(0, 2 * np.pi, 200)
    ax.plot(np.cos(ring), np.sin(ring), c="lightgrey", lw=6, zorder=1)
    stops = angle(np.arange(k))
    ax.scatter(np.cos(stops), np.sin(stops), s=60, c="white", edgecolors="black", zorder=2)
    for s, a in enumerate(stops):
        ax.annotate(f"stop {s + 1}", (1.22 * np.cos(a), 1.22 * np.sin(a)), ha="center",
                    va="center", fontsize=8)
    colours = [f"C{b % 10}" for b in range(n)]
    a = angle(frame.position)
    ax.scatter(np.cos(a), np.sin(a), s=140, c=colours, edgecolors="black", zorder=3)
    for b in range(n):
        ax.annotate(f"{b + 1}", (np.cos(a[b]), np.sin(a[b])), ha="center", va="center",
                    fontsize=7, color="white", zorder=4)
    ax.set_xlim(-1.45, 1.45)
    ax.set_ylim(-1.45, 1.45)
    ax.set_aspect("equal")
    ax.axis("off")
    hours, rest = divmod(frame.time, 3600)
    ax.set_title(f"bus corridor  t = {int(hours)}:{int(rest // 60):02d}:{int(rest % 60):02d}",
                 fontsize=10)
    bars.barh(np.arange(n), frame.load, color=colours)
    bars.set_xlim(0, cfg.l_max)
    bars.set_yticks(np.arange(n), [f"bus {b + 1}" for b in range(n)], fontsize=8)
    bars.invert_yaxis()
    bars.set_xlabel(f"load (passengers, capacity {cfg.l_max})", fontsize=8)
    bars.tick_params(axis="x", labelsize=8)
    fig.tight_layout()
