"""What a training run needs of the machine, estimated before it starts: a batch that cannot fit
in memory, or a network that cannot, is refused in one line rather than met by a MemoryError (or
the kernel's kill) once the first epoch allocates it."""

from __future__ import annotations

from typing import Any

from repro.core.memory import require_memory
from repro.core.rollout import rollout_bytes

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
    """Lower bounds of an epoch's memory: (for its batch, for its networks). The batch has at
    least one decision per agent per episode; per decision it holds the rollout's record, the
    standardised observations (float64 and float32) and the policy's activations; the networks
    hold their parameters ``PARAMETER_COPIES`` times."""
    decisions = cfg.batch_episodes * env.n_agents
    hidden = list(cfg.hidden)
    per_decision = (12 * env.obs_dim + DECISION_UPDATE_BYTES
                    + 4 * 2 * sum(hidden) + 4 * 3 * env.n_actions)
    batch = rollout_bytes(env, cfg.batch_episodes) + decisions * per_decision
    networks = 4 * PARAMETER_COPIES * network_parameters([env.obs_dim, *hidden, env.n_actions])
    return batch, networks


def check_training_size(cfg: Any, env: Any, runs: int = 1) -> None:
    """Refuse (UsageError naming --batch-episodes or --hidden, whichever needs more) a run, or
    ``runs`` runs at once, that cannot fit in this machine's memory."""
    batch, networks = training_bytes(cfg, env)
    param, got = (("--hidden", list(cfg.hidden)) if networks > batch
                  else ("--batch-episodes", cfg.batch_episodes))
    what = "a training epoch" if runs == 1 else f"{runs} training epochs at once"
    require_memory(runs * (batch + networks), param, got, what)
