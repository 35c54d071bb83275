"""One message-passing round of the processor (article 4.3, eqs. 8-11)."""

from __future__ import annotations

import torch
from torch_geometric.nn import MessagePassing

from surrogate.model.mlp import MLP


class Updater(MessagePassing):
    r"""Updater :math:`u_q` with residual connections on nodes and edges:

    .. math::
        e'_{ij} = \mathrm{MLP}(v_i, e_{ij}, v_j), \qquad
        v'_j = \mathrm{MLP}\Big(v_j, \sum_{i \in N_j} e'_{ij}\Big), \qquad
        e_{ij} \leftarrow e_{ij} + e'_{ij}, \quad v_j \leftarrow v_j + v'_j

    ``edge_index[0]`` holds senders :math:`i`, ``edge_index[1]`` receivers :math:`j`.
    """

    def __init__(self, latent: int, hidden: int, layers: int = 3):
        super().__init__(aggr="add", flow="source_to_target")
        self.edge_mlp = MLP(3 * latent, hidden, latent, layers)
        self.node_mlp = MLP(2 * latent, hidden, latent, layers)

    def forward(self, v: torch.Tensor, e: torch.Tensor, edge_index: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        sender, receiver = edge_index
        e_new = self.edge_mlp(torch.cat([v[sender], e, v[receiver]], dim=-1))
        aggregated = self.propagate(edge_index, message_value=e_new, size=(v.size(0), v.size(0)))
        v_new = self.node_mlp(torch.cat([v, aggregated], dim=-1))
        return v + v_new, e + e_new

    def message(self, message_value: torch.Tensor) -> torch.Tensor:
        return message_value
