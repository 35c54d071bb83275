"""The MLP used everywhere in Graph-DEM (article 4.5)."""

from __future__ import annotations

from torch import nn


class MLP(nn.Sequential):
    r"""Three linear layers with ReLU between them and LayerNorm at the end (article 4.5):

    .. math::
        H_1 = \mathrm{ReLU}(W_1 I + b_1),\; H_2 = \mathrm{ReLU}(W_2 H_1 + b_2),\;
        H_3 = W_3 H_2 + b_3,\; O = \mathrm{LayerNorm}(H_3)

    The generator's MLP has no LayerNorm (``layer_norm=False``, O = H_3).
    """

    def __init__(self, in_dim: int, hidden: int, out_dim: int, layers: int = 3, layer_norm: bool = True):
        dims = [in_dim] + [hidden] * (layers - 1) + [out_dim]
        modules: list[nn.Module] = []
        for k in range(layers):
            modules.append(nn.Linear(dims[k], dims[k + 1]))
            if k < layers - 1:
                modules.append(nn.ReLU())
        if layer_norm:
            modules.append(nn.LayerNorm(out_dim))
        super().__init__(*modules)
