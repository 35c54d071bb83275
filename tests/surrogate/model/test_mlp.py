"""The MLP of Graph-DEM (article 4.5): linear layers with ReLU between them and LayerNorm at the end, or none."""

import torch

from surrogate.model.mlp import MLP


def test_the_layers_compute_the_article_s_formula():
    torch.manual_seed(0)
    mlp = MLP(4, 8, 3, layers=3).double()
    x = torch.randn(5, 4, dtype=torch.float64)
    (w1, b1), (w2, b2), (w3, b3) = [(m.weight, m.bias) for m in mlp if isinstance(m, torch.nn.Linear)]
    h3 = torch.relu(torch.relu(x @ w1.T + b1) @ w2.T + b2) @ w3.T + b3
    norm = mlp[-1]
    expected = (h3 - h3.mean(-1, keepdim=True)) / torch.sqrt(h3.var(-1, unbiased=False, keepdim=True) + norm.eps)
    torch.testing.assert_close(mlp(x), expected * norm.weight + norm.bias)
    # freshly made, LayerNorm's scale is 1 and shift 0: each output row has mean 0 and variance 1
    torch.testing.assert_close(mlp(x).mean(-1), torch.zeros(5, dtype=torch.float64))


def test_without_layer_norm_the_output_is_the_last_linear_layer_s():
    torch.manual_seed(1)
    mlp = MLP(2, 6, 2, layers=2, layer_norm=False).double()
    assert [type(m).__name__ for m in mlp] == ["Linear", "ReLU", "Linear"]
    x = torch.randn(3, 2, dtype=torch.float64)
    torch.testing.assert_close(mlp(x), mlp[2](torch.relu(mlp[0](x))))
    assert [m.out_features for m in MLP(5, 7, 1, layers=4) if isinstance(m, torch.nn.Linear)] == [7, 7, 7, 1]
