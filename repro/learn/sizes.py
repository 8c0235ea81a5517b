"""What a training run needs of the machine, estimated before it starts: a batch that cannot fit
in memory, or a network that cannot, is refused in one line rather than met by a MemoryError (or
the kernel's kill) once the first epoch allocates it."""

from __future__ import annotations

from typing import Any

from repro.core.rollout import DECISION_BYTES, rollout_bytes
from repro.runs.memory import require_memory

PARAMETER_COPIES = 10
"""float32 copies of the policy's parameters a TRPO step holds at once (the network, its
gradient, conjugate-gradient vectors, the step and the parameters before the line search)."""
DECISION_UPDATE_BYTES = 64
"""Float64 numbers an update keeps per decision besides the network's activations (returns,
advantages, baseline values and their standardised copies)."""


def network_parameters(sizes: list[int]) -> int:
    """Weights and biases of an MLP through layer ``sizes`` (inputs first)."""
    return sum((a + 1) * b for a, b in zip(sizes, sizes[1:]))


def training_bytes(cfg: Any, env: Any) -> tuple[int, int]:
    """Lower bounds of an epoch's memory: (for its batch, for its networks). A batch counted in
    episodes has at least one decision per agent per episode, one counted in decisions at least
    its decisions and an episode per sampling worker; per decision it holds the rollout's record,
    the standardised observations (float64 and float32) and the policy's activations; the
    networks hold their parameters ``PARAMETER_COPIES`` times."""
    hidden = list(cfg.hidden)
    per_decision = (12 * env.obs_dim + DECISION_UPDATE_BYTES
                    + 4 * 2 * sum(hidden) + 4 * 3 * env.n_actions)
    episodes = getattr(cfg, "batch_episodes", None)
    if episodes is not None:
        decisions = episodes * env.n_agents
        batch = rollout_bytes(env, episodes) + decisions * per_decision
    else:  # counted in decisions (the released runner's batch)
        decisions = cfg.batch_decisions
        batch = (getattr(cfg, "batch_workers", 1) * int(getattr(env, "episode_bytes", 0))
                 + decisions * (per_decision + DECISION_BYTES + 8 * env.obs_dim))
    networks = 4 * PARAMETER_COPIES * network_parameters([env.obs_dim, *hidden, env.n_actions])
    return batch, networks


def check_training_size(cfg: Any, env: Any, runs: int = 1) -> None:
    """Refuse (UsageError naming the batch's size or --hidden, whichever needs more) a run, or
    ``runs`` runs at once, that cannot fit in this machine's memory."""
    batch, networks = training_bytes(cfg, env)
    size = (("--batch-episodes", cfg.batch_episodes)
            if getattr(cfg, "batch_episodes", None) is not None
            else ("--batch-decisions", cfg.batch_decisions))
    param, got = ("--hidden", list(cfg.hidden)) if networks > batch else size
    what = "a training epoch" if runs == 1 else f"{runs} training epochs at once"
    require_memory(runs * (batch + networks), param, got, what)
