"""The policy network's derivatives written out: a forward pass that keeps what they need, and the
two Jacobian products a TRPO step is made of, for the tanh MLP of :func:`repro.learn.policy.mlp`.

Why not autograd: on the paper's wildfire batch (25,000-35,000 decisions, a 2x32 network) the
Fisher-vector products through autograd's double backward, and log_softmax along rows of a few
entries, made the TRPO step about twice the simulation. Written out, a Fisher-vector product is
half the work; tests check every product against autograd on the same module, and the forward
pass layer by layer against the network's spec (tests/test_policy_network.py).

Layout: inputs and hidden activations are sample-major, (N, units), as torch's ``Linear`` computes
them; the logits are action-major, (n_actions, N), because a softmax over a few long rows is one
vectorised operation per row, ten times faster than over N rows of a few entries. Everything runs
under ``torch.no_grad`` in the network's dtype (float32 in training).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch
from torch import nn


@dataclass
class Forward:
    """One forward pass over a batch, with what the Jacobian products reuse."""

    x: torch.Tensor
    """Inputs, (N, in_dim)."""
    hidden: list[torch.Tensor]
    """tanh activations of each hidden layer, (N, units)."""
    logits: torch.Tensor
    """Outputs, action-major: (n_actions, N)."""
    _slopes: list[torch.Tensor] | None = field(default=None, repr=False)

    @property
    def slopes(self) -> list[torch.Tensor]:
        """tanh' = 1 - h^2 of each hidden layer (computed once: every product needs them)."""
        if self._slopes is None:
            self._slopes = [1.0 - h * h for h in self.hidden]
        return self._slopes

    def rows(self, index: torch.Tensor) -> Forward:
        """The same pass restricted to the batch entries ``index``."""
        return Forward(self.x[index], [h[index] for h in self.hidden], self.logits[:, index])


class TanhMLP:
    """The ``Linear`` layers of a tanh MLP, their parameters also seen as one flat vector in
    ``parameters_to_vector`` order (per layer: weight rows, then bias)."""

    def __init__(self, net: nn.Sequential):
        self.layers = [(m.weight, m.bias) for m in net if isinstance(m, nn.Linear)]
        self.sizes = [t.numel() for layer in self.layers for t in layer]
        self.dtype = self.layers[0][0].dtype

    @torch.no_grad()
    def get_flat(self) -> torch.Tensor:
        return torch.cat([t.reshape(-1) for layer in self.layers for t in layer])

    @torch.no_grad()
    def set_flat(self, theta: torch.Tensor) -> None:
        """Write ``theta`` into the parameters in place (cast to their dtype)."""
        for t, piece in zip((t for layer in self.layers for t in layer), self._pieces(theta)):
            t.copy_(piece)

    def _pieces(self, v: torch.Tensor) -> list[torch.Tensor]:
        flat = torch.split(v.to(self.dtype), self.sizes)
        return [p.view_as(t) for p, t in zip(flat, (t for layer in self.layers for t in layer))]

    @torch.no_grad()
    def forward(self, x: torch.Tensor) -> Forward:
        """The pass over inputs ``x`` (N, in_dim)."""
        a, hidden = x, []
        for w, b in self.layers[:-1]:
            a = torch.tanh(torch.addmm(b, a, w.T))
            hidden.append(a)
        w, b = self.layers[-1]
        return Forward(x, hidden, torch.addmm(b[:, None], w, a.T))

    @torch.no_grad()
    def jvp(self, fwd: Forward, v: torch.Tensor) -> torch.Tensor:
        """J v: the change of the logits (n_actions, N) along the parameter direction ``v``."""
        pieces = self._pieces(v)
        inputs = [fwd.x, *fwd.hidden]
        da = None  # the inputs do not depend on the parameters
        for i, (w, _) in enumerate(self.layers[:-1]):
            dw, db = pieces[2 * i], pieces[2 * i + 1]
            dy = torch.addmm(db, inputs[i], dw.T)
            if da is not None:
                dy.addmm_(da, w.T)
            da = dy.mul_(fwd.slopes[i])
        w = self.layers[-1][0]
        dz = torch.addmm(pieces[-1][:, None], pieces[-2], inputs[-1].T)
        return dz if da is None else dz.addmm_(w, da.T)

    @torch.no_grad()
    def vjp(self, fwd: Forward, g: torch.Tensor) -> torch.Tensor:
        """J' g: the gradient of sum(g * logits), g (n_actions, N), as a flat vector."""
        inputs = [fwd.x, *fwd.hidden]
        g = g.to(self.dtype)
        pieces = [g.sum(dim=1), g @ inputs[-1]]  # built from the last parameter backwards
        delta = (g.T @ self.layers[-1][0]) if len(self.layers) > 1 else None
        for i in range(len(self.layers) - 2, -1, -1):
            delta.mul_(fwd.slopes[i])
            pieces += [delta.sum(dim=0), delta.T @ inputs[i]]
            if i > 0:
                delta = delta @ self.layers[i][0]
        return torch.cat([p.reshape(-1) for p in reversed(pieces)])


def log_softmax(logits: torch.Tensor) -> torch.Tensor:
    """Log-probabilities of action-major logits (n_actions, N)."""
    return torch.log_softmax(logits, dim=0)
