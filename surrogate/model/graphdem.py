"""Graph-DEM: constructor -> processor (Q updaters) -> generator (article 4.1)."""

from __future__ import annotations

import torch
from torch import nn

from surrogate.model.constructor import EdgeConstructor, NodeConstructor
from surrogate.model.mlp import MLP
from surrogate.model.updater import Updater


class GraphDEM(nn.Module):
    r"""Predicts the normalised acceleration :math:`\ddot P^{t+1} = \mathrm{GraphDEM}(X^{t-K+1:t})` (eq. 3).

    The generator is :math:`\ddot p_j^{t+1} = \mathrm{MLP}(v_j^Q)` without LayerNorm (eq. 12). With ``bundle`` = B
    (temporal bundling; 1: the article's model) it predicts the next B frames' accelerations at once,
    :math:`(\ddot p_j^{t+1}, \dots, \ddot p_j^{t+B}) = \mathrm{MLP}(v_j^Q)`, a vector of B D entries.
    ``edge_features`` names optional edge inputs beyond eq. (7)
    (:func:`surrogate.model.constructor.edge_inputs`; none: the article's model).
    """

    def __init__(self, dim: int, history: int, n_types: int, n_props: int = 0, latent: int = 128,
                 hidden: int = 128, message_passing: int = 10, embed: int = 16, layers: int = 3,
                 split_edge_mlp: bool = True, edge_features=(), bundle: int = 1):
        super().__init__()
        self.node_constructor = NodeConstructor(dim, history, n_types, n_props, latent, hidden, embed, layers)
        self.edge_constructor = EdgeConstructor(dim, latent, hidden, layers, edge_features)
        self.processor = nn.ModuleList(Updater(latent, hidden, layers, split_edge_mlp) for _ in range(message_passing))
        self.generator = MLP(latent, hidden, dim * bundle, layers, layer_norm=False)

    def forward(self, velocities: torch.Tensor, types: torch.Tensor, boundary: torch.Tensor, pos: torch.Tensor,
                edge_index: torch.Tensor, radius: float, props: torch.Tensor | None = None,
                decode: torch.Tensor | None = None, velocity: torch.Tensor | None = None,
                radii: torch.Tensor | None = None) -> torch.Tensor:
        """Accelerations ``[N, B D]`` of every node, or only of the nodes ``decode`` (indices) when given. ``velocity``
        (the last velocity, length per frame) and ``radii`` feed the optional edge features that need them."""
        v = self.node_constructor(velocities, types, boundary, props)
        e = self.edge_constructor(pos, edge_index, radius, velocity, radii)
        for updater in self.processor:
            v, e = updater(v, e, edge_index)
        return self.generator(v if decode is None else v[decode])
