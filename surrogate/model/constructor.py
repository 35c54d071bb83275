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


#: optional edge inputs beyond eq. (7), in the order they are appended (``model.edge_features``)
EDGE_FEATURES = ("relative_velocity", "projected_distance", "gap")


def edge_feature_width(dim: int, features: tuple[str, ...] | list[str]) -> int:
    """Entries each edge's input vector has: eq. (7)'s D + 1 plus those of the optional ``features``."""
    check_edge_features(features)
    return dim + 1 + sum(dim if name == "relative_velocity" else 1 for name in features)


def check_edge_features(features) -> None:
    """Refuse an unknown or repeated optional edge feature, naming it and what is allowed."""
    for name in features:
        if name not in EDGE_FEATURES:
            raise ValueError(f"model.edge_features: unknown edge feature {name!r}; allowed: {', '.join(EDGE_FEATURES)}")
    if len(set(features)) != len(features):
        raise ValueError(f"model.edge_features lists a feature twice: {list(features)}")


def edge_inputs(pos: torch.Tensor, edge_index: torch.Tensor, radius: float, features=(),
                velocity: torch.Tensor | None = None, radii: torch.Tensor | None = None) -> torch.Tensor:
    r"""Each edge's input vector: eq. (7)'s :math:`d_{ij}/R, |d_{ij}|/R` with :math:`d_{ij} = p_j - p_i`
    (i the sender, j the receiver), then, in the order of :data:`EDGE_FEATURES`, those ``features`` asks for:

    * ``relative_velocity``: :math:`(\dot p_j - \dot p_i)/R`, the last velocities (length per frame);
    * ``projected_distance``: :math:`|d_{ij} + \dot p_j - \dot p_i|/R`, the pair's distance one frame on at
      constant velocity: whether the two meet before the next frame;
    * ``gap``: :math:`(|d_{ij}| - r_i - r_j)/R`, the surface gap (negative: overlap), from the radii ``radii``.

    Every entry is a difference between the pair, so the edge inputs do not change when every particle
    is moved by the same vector (and, for the velocity terms, given the same extra velocity)."""
    sender, receiver = edge_index
    disp = (pos[receiver] - pos[sender]) / radius
    distance = disp.norm(dim=-1, keepdim=True)
    parts = [disp, distance]
    wanted = set(features)
    if wanted & {"relative_velocity", "projected_distance"}:
        if velocity is None:
            raise ValueError("the edge features relative_velocity and projected_distance need the particles' velocity")
        relative = (velocity[receiver] - velocity[sender]) / radius
        if "relative_velocity" in wanted:
            parts.append(relative)
        if "projected_distance" in wanted:
            parts.append((disp + relative).norm(dim=-1, keepdim=True))
    if "gap" in wanted:
        if radii is None:
            raise ValueError("the edge feature gap needs the particles' radii (model.properties must list radius)")
        parts.append(distance - (radii[sender] + radii[receiver]).unsqueeze(-1) / radius)
    return torch.cat(parts, dim=-1)


class EdgeConstructor(nn.Module):
    r"""Edge features (article eq. 7): :math:`e_{ij}^0 = \mathrm{MLP}((p_j - p_i)/R, |p_j - p_i|/R)`,
    with the optional inputs ``features`` (:func:`edge_inputs`) appended to the MLP's input."""

    def __init__(self, dim: int, latent: int, hidden: int, layers: int = 3, features=()):
        super().__init__()
        self.features = tuple(features)
        self.in_dim = edge_feature_width(dim, self.features)
        self.mlp = MLP(self.in_dim, hidden, latent, layers)

    def forward(self, pos: torch.Tensor, edge_index: torch.Tensor, radius: float,
                velocity: torch.Tensor | None = None, radii: torch.Tensor | None = None) -> torch.Tensor:
        return self.mlp(edge_inputs(pos, edge_index, radius, self.features, velocity, radii))
