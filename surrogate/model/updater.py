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

    With ``split_edge_mlp`` the first layer of the edge MLP is evaluated as
    :math:`W_1 [v_i, e_{ij}, v_j] = (W_s v)_i + W_e e_{ij} + (W_r v)_j`: the node terms once per
    node and gathered, instead of once per edge. The weights are the same; only the arithmetic is
    regrouped, so the result is equal up to rounding.
    """

    def __init__(self, latent: int, hidden: int, layers: int = 3, split_edge_mlp: bool = True):
        super().__init__(aggr="add", flow="source_to_target")
        self.latent = latent
        self.split_edge_mlp = split_edge_mlp
        self.edge_mlp = MLP(3 * latent, hidden, latent, layers)
        self.node_mlp = MLP(2 * latent, hidden, latent, layers)

    def edge_messages(self, v: torch.Tensor, e: torch.Tensor, edge_index: torch.Tensor) -> torch.Tensor:
        r""":math:`e'_{ij} = \mathrm{MLP}(v_i, e_{ij}, v_j)` (eq. 8)."""
        sender, receiver = edge_index
        if not self.split_edge_mlp:
            return self.edge_mlp(torch.cat([v[sender], e, v[receiver]], dim=-1))
        first = self.edge_mlp[0]
        w_s, w_e, w_r = first.weight.split(self.latent, dim=1)
        node_terms = v @ torch.cat([w_s, w_r]).T                    # [N, 2H]: sender and receiver parts
        s_part, r_part = node_terms.split(first.out_features, dim=1)
        h = torch.addmm(first.bias, e, w_e.T) + s_part[sender] + r_part[receiver]
        for module in list(self.edge_mlp)[1:]:
            h = module(h)
        return h

    def forward(self, v: torch.Tensor, e: torch.Tensor, edge_index: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        e_new = self.edge_messages(v, e, edge_index)
        aggregated = self.propagate(edge_index, message_value=e_new, size=(v.size(0), v.size(0)))
        v_new = self.node_mlp(torch.cat([v, aggregated], dim=-1))
        return v + v_new, e + e_new

    def message(self, message_value: torch.Tensor) -> torch.Tensor:
        return message_value
