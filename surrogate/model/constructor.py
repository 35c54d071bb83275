"""Constructor (article 4.2): node and edge feature vectors of the graph G^0."""

from __future__ import annotations

import torch
from torch import nn

from surrogate.model.mlp import MLP


class NodeConstructor(nn.Module):
    r"""Node features (article eq. 4-6):

    .. math::
        v_i^0 = \mathrm{MLP}(\dot p_i^{t-K+2:t}, \varepsilon(T_i), f_i, B_i^t), \quad
        \varepsilon(T_i) = W^\varepsilon_{T_i,:}, \quad
        B_i^t = \{\min(x_i - b_l, R)/R,\ \min(b_r - x_i, R)/R, \dots\}

    Velocities arrive normalised; B has two entries per axis, so 4 in 2D and 6 in 3D. ``n_props``
    is 0 for a scene without per-particle properties: no property feature exists then.
    """

    def __init__(self, dim: int, history: int, n_types: int, n_props: int, latent: int, hidden: int,
                 embed: int = 16, layers: int = 3):
        super().__init__()
        self.embedding = nn.Embedding(n_types, embed)
        self.in_dim = (history - 1) * dim + embed + n_props + 2 * dim
        self.mlp = MLP(self.in_dim, hidden, latent, layers)

    def forward(self, velocities: torch.Tensor, types: torch.Tensor, boundary: torch.Tensor,
                props: torch.Tensor | None = None) -> torch.Tensor:
        parts = [velocities.flatten(1), self.embedding(types)]
        if props is not None:
            parts.append(props)
        parts.append(boundary)
        return self.mlp(torch.cat(parts, dim=-1))


def boundary_features(pos: torch.Tensor, lower: torch.Tensor, upper: torch.Tensor, radius: float) -> torch.Tensor:
    """Clipped distances to the lower and upper boundary of every axis, divided by R (eq. 6)."""
    return torch.cat([torch.clamp(pos - lower, max=radius), torch.clamp(upper - pos, max=radius)], dim=-1) / radius


class EdgeConstructor(nn.Module):
    r"""Edge features (article eq. 7): :math:`e_{ij}^0 = \mathrm{MLP}((p_j - p_i)/R, |p_j - p_i|/R)`."""

    def __init__(self, dim: int, latent: int, hidden: int, layers: int = 3):
        super().__init__()
        self.mlp = MLP(dim + 1, hidden, latent, layers)

    def forward(self, pos: torch.Tensor, edge_index: torch.Tensor, radius: float) -> torch.Tensor:
        sender, receiver = edge_index
        disp = (pos[receiver] - pos[sender]) / radius
        return self.mlp(torch.cat([disp, disp.norm(dim=-1, keepdim=True)], dim=-1))
