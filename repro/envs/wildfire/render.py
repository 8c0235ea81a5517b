"""Pictures of a wildfire episode: what a frame shows, from either engine, drawn with matplotlib.

A :class:`Frame` is the state at one instant: every fire (position, health left, out or burning,
its extinguish party) and every UAV (position, the fire whose interest party it is in). The fast
engine's state (:func:`frame_of_state`) and the SimPy model (:func:`frame_of_model`, which the
PettingZoo view runs) give the same frame, through each engine's own position and health rules.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from repro.envs.wildfire.params import WildfireConfig, fire_positions


@dataclass(frozen=True)
class Frame:
    """The wildfire at one instant."""

    time: float
    """Simulation time (s)."""
    fires: np.ndarray
    """(K, 2) fire positions."""
    health: np.ndarray
    """(K,) health left (0 once out)."""
    alive: np.ndarray
    """(K,) bool: still burning."""
    party: np.ndarray
    """(K,) UAVs extinguishing the fire now."""
    uavs: np.ndarray
    """(N, 2) UAV positions."""
    target: np.ndarray
    """(N,) the fire whose interest party each UAV is in (its target), -1 for none."""


def frame_of_state(env, state: np.void) -> Frame:
    """The frame of one episode's state record of the fast engine ``env`` (a WildfireEnv)."""
    from repro.envs.wildfire.engine import _health_now, _position

    params = env.params[0]
    k, n = len(state["alive"]), len(state["interest"])
    return Frame(time=float(state["now"]), fires=fire_positions(env.cfg),
                 health=np.array([_health_now(state, params, j) for j in range(k)]),
                 alive=state["alive"].astype(bool), party=state["party"].astype(np.int64),
                 uavs=np.array([_position(state, params, i) for i in range(n)]),
                 target=state["interest"].astype(np.int64))


def frame_of_model(model) -> Frame:
    """The frame of the SimPy model (:class:`repro.envs.wildfire.reference.WildfireModel`)."""
    k, n = len(model.fire), len(model.uav)
    return Frame(time=float(model.env.now), fires=np.asarray(model.fire_xy, float),
                 health=np.array([model._health_now(j) for j in range(k)]),
                 alive=np.array([fire.alive for fire in model.fire], bool),
                 party=np.array([fire.party for fire in model.fire], np.int64),
                 uavs=np.array([model._position(i) for i in range(n)], float),
                 target=np.array([uav.interest for uav in model.uav], np.int64))


def draw(fig, frame: Frame, cfg: WildfireConfig) -> None:
    """Draw ``frame`` on the matplotlib figure ``fig`` (cleared first). Left, the map: burning
    fires red, larger and darker with more health left, fires out grey crosses; UAVs blue
    triangles, each with a dashed line to its target fire. Right, every fire's health left, the
    number of UAVs extinguishing it, or "out" (the fires stand in tight clusters of three, too close
    on the map to label)."""
    fig.clear()
    ax, bars = fig.subplots(1, 2, gridspec_kw={"width_ratios": [3, 2]})
    side = max(1.0, float(np.abs(frame.fires).max())) * 1.15
    ax.set_xlim(-side, side)
    ax.set_ylim(-side, side)
    ax.set_aspect("equal")
    ax.grid(alpha=0.2)
    left = np.clip(frame.health / cfg.t_health, 0.0, 1.0)
    burning = frame.alive
    if burning.any():  # (an empty array of alphas is refused)
        ax.scatter(*frame.fires[burning].T, s=60 + 300 * left[burning], c="tab:red",
                   alpha=0.3 + 0.5 * left[burning], edgecolors="darkred", zorder=2)
    ax.scatter(*frame.fires[~burning].T, s=60, marker="x", c="grey", zorder=2)
    for i, (x, y) in enumerate(frame.uavs):
        j = frame.target[i]
        if j >= 0:
            ax.plot([x, frame.fires[j, 0]], [y, frame.fires[j, 1]], "--", c="tab:blue", lw=0.8,
                    alpha=0.6, zorder=1)
        ax.annotate(f"U{i}", (x, y), xytext=(7, -3), textcoords="offset points", fontsize=8,
                    color="navy")
    ax.scatter(*frame.uavs.T, marker="^", s=80, c="tab:blue", edgecolors="navy", zorder=3)
    ax.set_title(f"t = {frame.time:.2f} s: {int(burning.sum())} of {len(burning)} fires burning",
                 fontsize=10)
    k = len(frame.fires)
    health = np.where(burning, np.clip(frame.health, 0.0, None), 0.0)
    bars.barh(np.arange(k), health, color=np.where(burning, "tab:red", "grey"))
    bars.set_xlim(0, cfg.t_health * 1.6)
    bars.set_yticks(np.arange(k), [f"fire {j}" for j in range(k)], fontsize=8)
    bars.invert_yaxis()
    bars.set_xlabel("health left (UAV-seconds)", fontsize=8)
    bars.tick_params(axis="x", labelsize=8)
    for j in range(k):
        note = "out" if not burning[j] else (f"{frame.party[j]} UAV" if frame.party[j] else "")
        bars.annotate(note, (health[j], j), xytext=(3, 0), textcoords="offset points",
                      va="center", fontsize=8)
    fig.tight_layout()
