"""render: an animation of one episode of a policy, a GIF a person can watch.

The episode runs on the environment's fast engine; its state is pictured (``repro.envs.<env>.
render``) after every round of decisions, and the GIF shows ``--frames`` of those pictures evenly
spaced in simulated time (the last one the episode's end). Wildfire policies: ``random``,
``nearest``, ``flowchart`` (``repro.envs.wildfire.policies``), ``checkpoint PATH`` (a training
run's ``checkpoint.pt``, on that run's environment settings); bus policies: ``nohold``,
``authors``, ``thresholds``, ``mlp [RUN]`` (``repro.studies.bus.policies``, reading
``--results-dir`` as ``bus-eval`` does), ``gru RUN``, ``gru-greedy RUN`` and ``checkpoint PATH``.
``--results-dir`` is refused where the chosen policy reads nothing there. The GIF's sidecar
(``episode.provenance.json`` beside ``episode.gif``) records the command, the policy, the hash of
the policy's file where one is named, the commit and the versions. Bad input is one line, exit
status 2, and nothing is written.
"""

from __future__ import annotations

import argparse
import hashlib
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from repro.core.errors import refuse_unused, require
from repro.learn.trained_policy import (check_fits, load_trained_run, policy_from_state,
                                        trained_env_config)
from repro.runs.files import check_names, check_writable_dir
from repro.runs.results import write_figure
from repro.studies.bus import policies as bus_policies

POLICIES = {"wildfire": ("random", "nearest", "flowchart", "checkpoint"),
            "bus": (*bus_policies.POLICIES, "checkpoint")}
"""Environment -> the policies it pictures."""
WITH_PATH = {"checkpoint": "PATH", "mlp": "[RUN]", "gru": "RUN", "gru-greedy": "RUN"}
"""Policies that take a path after their name: what it is (in brackets where it is optional)."""
RESULTS_DIR = "results/paper"
"""Where the bus policies thresholds and mlp find their results without --results-dir."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--env", default="wildfire", help="wildfire or bus")
    p.add_argument("--policy", nargs="+", metavar="NAME [PATH]", default=None,
                   help="the policy: NAME, or NAME PATH. wildfire: random (default), nearest, "
                        "flowchart, or checkpoint PATH (a training run's checkpoint.pt, on that "
                        "run's environment settings); bus: nohold (default), authors, "
                        "thresholds, mlp [RUN] (thresholds and mlp read --results-dir, as "
                        "bus-eval does), gru RUN, gru-greedy RUN, or checkpoint PATH")
    p.add_argument("--out", required=True, help="the GIF to write (.gif)")
    p.add_argument("--seed", type=int, default=0, help="the episode (wildfire) and the policy's "
                                                       "random source")
    p.add_argument("--frames", type=int, default=120, help="pictures in the animation, at most")
    p.add_argument("--fps", type=int, default=8, help="pictures per second of the animation")
    p.add_argument("--results-dir", help="where the bus policies thresholds and mlp find their "
                   f"results (default: {RESULTS_DIR})")


@dataclass(frozen=True)
class RenderConfig:
    """What ``render`` animates, and where it writes."""

    env: str
    """The environment, wildfire or bus (``--env``)."""
    policy: str
    """The policy's name (``--policy NAME``)."""
    path: str | None
    """The run folder or checkpoint the policy comes from (``--policy NAME PATH``), if any."""
    out: Path
    """The GIF to write (``--out``)."""
    seed: int
    """The episode (wildfire) and the policy's random source (``--seed``)."""
    frames: int
    """Pictures in the animation, at most (``--frames``)."""
    fps: int
    """Pictures per second of the animation (``--fps``)."""
    results_dir: Path
    """Where the bus policies thresholds and mlp find their results (``--results-dir``)."""


def configure(args: argparse.Namespace) -> RenderConfig:
    """The settings of :func:`add_arguments`'s options, checked before any work (the GIF's folder
    writable)."""
    require(args.env in POLICIES, "--env", "wildfire or bus", args.env)
    name, *path = args.policy or [POLICIES[args.env][0]]
    require(name in POLICIES[args.env], "--policy", f"one of {', '.join(POLICIES[args.env])} "
            f"for --env {args.env}", name)
    need = WITH_PATH.get(name)
    optional = need is None or need.startswith("[")
    require(len(path) <= (need is not None) and (optional or path), "--policy",
            f"{name} {need or 'with no path'}", " ".join([name, *path]))
    if path:
        check_names(path[0], "--policy")
    reads_results = args.env == "bus" and (name == "thresholds" or (name == "mlp" and not path))
    refuse_unused(("--results-dir", args.results_dir, reads_results,
                   "with the bus policies thresholds, or mlp without a RUN (they read it)"))
    out = Path(args.out)
    require(out.suffix == ".gif", "--out", "a .gif file", args.out)
    require(out.parent.is_dir(), "--out", "in an existing folder", args.out)
    check_writable_dir(out.parent, "--out")  # before the episode runs
    require(args.frames >= 2, "--frames", "an integer >= 2", args.frames)
    require(args.fps >= 1, "--fps", "an integer >= 1", args.fps)
    return RenderConfig(env=args.env, policy=name, path=path[0] if path else None, out=out,
                        seed=args.seed, frames=args.frames, fps=args.fps,
                        results_dir=Path(args.results_dir or RESULTS_DIR))


def run(cfg: RenderConfig) -> int:
    rng = np.random.default_rng(cfg.seed)
    episode = _wildfire if cfg.env == "wildfire" else _bus
    times, pictures, draw = episode(cfg, rng)
    gif = _animate(times, pictures, draw, cfg.frames, cfg.fps)
    write_figure(cfg.out.with_suffix(""), {cfg.out: gif.data}, [], param="--out",
                 extra={"policy": cfg.policy, "policy_file": _file_record(cfg.path)})
    shown = gif.pictures
    print(f"wrote {cfg.out}: {shown} pictures of an episode of "
          f"{times[-1]:.1f} s ({cfg.env}, {cfg.policy})")
    return 0


def _file_record(path: str | None) -> dict[str, str] | None:
    """The path and SHA-256 of a policy's file (a checkpoint), None where the policy names no file
    (a run folder's is the one its config picks)."""
    if path is None or not Path(path).is_file():
        return None
    return {"path": path, "sha256": hashlib.sha256(Path(path).read_bytes()).hexdigest()}


def _trained(path: str, env_name: str, config_type: type, rng: np.random.Generator):
    """The environment config and the policy of a trained run's checkpoint."""
    from repro.envs import env_package

    state = load_trained_run(path, env_name, "--policy")
    cfg = trained_env_config(state, config_type, "--policy")
    check_fits(state, env_package(env_name).make_env(cfg), "--policy", path)
    return cfg, policy_from_state(state, rng)


def _wildfire(render: RenderConfig, rng: np.random.Generator):
    """The episode's pictures; returns (times, frames, draw)."""
    from repro.envs.wildfire import WildfireConfig
    from repro.envs.wildfire.engine import WildfireBatch, WildfireEnv
    from repro.envs.wildfire.params import draw_episodes
    from repro.envs.wildfire.policies import POLICIES as HEURISTICS
    from repro.envs.wildfire.render import draw, frame_of_state

    if render.policy == "checkpoint":
        cfg, policy = _trained(render.path, "wildfire", WildfireConfig, rng)
    else:
        cfg = WildfireConfig()
        policy = HEURISTICS[render.policy](rng, n_observed=cfg.n_observed)
    env = WildfireEnv(cfg)
    batch = WildfireBatch(env, draw_episodes(cfg, 1, render.seed))
    frames = _run(lambda: frame_of_state(env, batch.states[0]),
                  lambda: float(batch.states[0]["now"]), cfg.t_max / (100 * render.frames),
                  lambda: batch.n_pending > 0, lambda: batch.act(policy(batch.pending())))
    return [f.time for f in frames], frames, lambda fig, f: draw(fig, f, cfg)


def _bus(render: RenderConfig, rng: np.random.Generator):
    """The episode's pictures; returns (times, frames, draw)."""
    from repro.envs.bus import BusConfig
    from repro.envs.bus.engine import BusBatch
    from repro.envs.bus.render import draw, frame_of_state

    name, path = render.policy, render.path
    if name == "checkpoint":
        cfg, policy = _trained(path, "bus", BusConfig, rng)
    else:
        cfg = BusConfig()
        policy = bus_policies.make_policy(name, cfg, results_dir=render.results_dir,
                                          mlp_run=path, results_param="--results-dir",
                                          mlp_param="--policy", gru_run=path, gru_param="--policy")
    batch = BusBatch(cfg, 1)
    pending = [batch.advance(np.zeros(0, np.int64))]

    def act() -> None:
        pending[0] = batch.advance(policy(pending[0]))

    frames = _run(lambda: frame_of_state(cfg, batch.state(0)), lambda: float(batch.state(0)["now"]),
                  cfg.horizon / (4 * render.frames), lambda: len(pending[0]) > 0, act)
    return [f.time for f in frames], frames, lambda fig, f: draw(fig, f, cfg)


def _run(frame, now, spacing, pending, act) -> list:
    """Round after round until the episode ends, a picture whenever ``spacing`` seconds of
    simulated time passed since the last (and at the end): long episodes make many rounds."""
    frames = [frame()]
    while pending():
        act()
        if now() >= frames[-1].time + spacing or not pending():
            frames.append(frame())
    return frames


class Animation(NamedTuple):
    data: bytes
    """The GIF's bytes."""
    pictures: int
    """How many pictures it shows."""


def _animate(times: list[float], frames: list, draw, n: int, fps: int) -> Animation:
    """``n`` of ``frames`` evenly spaced in time (each the latest at its instant), as a GIF."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.animation import FuncAnimation, PillowWriter
    from matplotlib.figure import Figure

    at = np.searchsorted(times, np.linspace(times[0], times[-1], n), side="right") - 1
    at = np.unique(at)  # a long round holds the picture; no repeats
    fig = Figure(figsize=(9, 4.5), dpi=80)
    animation = FuncAnimation(fig, lambda k: draw(fig, frames[at[k]]), frames=len(at))
    with tempfile.TemporaryDirectory() as folder:  # Pillow writes to a file name
        part = Path(folder) / "animation.gif"
        animation.save(part, writer=PillowWriter(fps=fps))
        return Animation(part.read_bytes(), len(at))
