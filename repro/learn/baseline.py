"""The value baseline V(o) that M-GAE subtracts.

Choice: a tanh MLP (same default shape as the policy) regressed on the M-GAE discounted returns of the
latest batch by a fixed number of full-batch L-BFGS iterations, like rllab's regressors. Targets are
standardised with the batch's mean and standard deviation, which are kept with the network, so the
same code works for the wildfire's returns of order 1 and the bus's of order 1e4. L-BFGS starts from
the previous epoch's network and keeps no state across epochs, so a checkpoint needs only the
network. Before its first fit the baseline predicts 0 (the first batch's advantages are returns).
"""

from __future__ import annotations

from typing import Sequence

import torch
from torch import nn

from repro.learn.policy import DTYPE, mlp


class ValueBaseline(nn.Module):
    def __init__(self, obs_dim: int, hidden: Sequence[int], iters: int):
        super().__init__()
        self.net = mlp(obs_dim, hidden, 1, out_gain=1.0)
        self.iters = iters
        self.register_buffer("target_mean", torch.zeros((), dtype=DTYPE))
        self.register_buffer("target_std", torch.ones((), dtype=DTYPE))
        self.register_buffer("fitted", torch.zeros((), dtype=torch.bool))

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """V of normalised observations, (N,)."""
        if not bool(self.fitted):
            return torch.zeros(len(obs), dtype=DTYPE)
        return self.target_mean + self.target_std * self.net(obs)[:, 0]

    def fit(self, obs: torch.Tensor, returns: torch.Tensor) -> float:
        """Regress on ``returns``; returns the final mean squared error in standardised units."""
        self.target_mean = returns.mean()
        self.target_std = returns.std(correction=0).clamp_min(1e-8)
        target = (returns - self.target_mean) / self.target_std
        opt = torch.optim.LBFGS(self.net.parameters(), max_iter=self.iters,
                                line_search_fn="strong_wolfe")

        def closure() -> torch.Tensor:
            opt.zero_grad()
            loss = ((self.net(obs)[:, 0] - target) ** 2).mean()
            loss.backward()
            return loss

        opt.step(closure)
        self.fitted = torch.ones((), dtype=torch.bool)
        with torch.no_grad():
            return float(((self.net(obs)[:, 0] - target) ** 2).mean())
