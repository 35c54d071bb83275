import numpy as np
import torch

from surrogate.graph import radius_graph
from surrogate.model.constructor import boundary_features
from surrogate.model.graphdem import GraphDEM


def test_article_sizes_give_about_1p6_million_parameters():
    model = GraphDEM(dim=2, history=6, n_types=3, latent=128, hidden=128, message_passing=10)
    assert sum(p.numel() for p in model.parameters()) == 1_591_730


def inputs(pos, radius, lower, upper, seed=0):
    g = torch.Generator().manual_seed(seed)
    n, dim = pos.shape
    vel = torch.randn(n, 5, dim, generator=g)
    types = torch.randint(0, 3, (n,), generator=g)
    return vel, types, boundary_features(pos, lower, upper, radius), radius_graph(pos, radius)


def test_prediction_is_invariant_to_translation_away_from_boundaries():
    torch.manual_seed(0)
    model = GraphDEM(dim=2, history=6, n_types=3, latent=32, hidden=32, message_passing=3).double()
    lower, upper, r = torch.zeros(2, dtype=torch.float64), torch.full((2,), 1000.0, dtype=torch.float64), 3.0
    pos = torch.tensor(np.random.default_rng(0).uniform(400, 420, (40, 2)))
    vel, types, bnd, edges = inputs(pos, r, lower, upper)
    shifted = pos + torch.tensor([123.4, -56.7], dtype=torch.float64)
    vel2, types2, bnd2, edges2 = inputs(shifted, r, lower, upper)
    assert torch.equal(bnd, bnd2) and torch.equal(edges, edges2)     # every boundary distance clipped at R
    out = model(vel, types, bnd, pos, edges, r)
    out2 = model(vel, types, bnd2, shifted, edges2, r)
    torch.testing.assert_close(out, out2, rtol=1e-9, atol=1e-9)


def test_boundary_features_are_clipped_distances_over_r():
    pos = torch.tensor([[1.0, 9.5], [5.0, 5.0]])
    b = boundary_features(pos, torch.zeros(2), torch.full((2,), 10.0), radius=2.0)
    torch.testing.assert_close(b, torch.tensor([[0.5, 1.0, 1.0, 0.25], [1.0, 1.0, 1.0, 1.0]]))


def test_3d_scene_with_properties_has_no_padding_and_uses_the_property():
    torch.manual_seed(0)
    model = GraphDEM(dim=3, history=6, n_types=2, n_props=1, latent=16, hidden=16, message_passing=2)
    assert model.node_constructor.in_dim == 5 * 3 + 16 + 1 + 6
    pos = torch.rand(10, 3)
    vel, types, bnd = torch.randn(10, 5, 3), torch.zeros(10, dtype=torch.long), torch.ones(10, 6)
    edges = radius_graph(pos, 0.5)
    a = model(vel, types, bnd, pos, edges, 0.5, props=torch.zeros(10, 1))
    b = model(vel, types, bnd, pos, edges, 0.5, props=torch.ones(10, 1))
    assert a.shape == (10, 3) and not torch.allclose(a, b)


def test_split_edge_mlp_gives_the_concatenated_first_layer_result():
    torch.manual_seed(0)
    concat = GraphDEM(dim=2, history=3, n_types=2, latent=24, hidden=20, message_passing=3,
                      split_edge_mlp=False).double()
    split = GraphDEM(dim=2, history=3, n_types=2, latent=24, hidden=20, message_passing=3,
                     split_edge_mlp=True).double()
    split.load_state_dict(concat.state_dict())        # same weights: only the arithmetic is regrouped
    pos = torch.tensor(np.random.default_rng(1).uniform(0, 10, (30, 2)))
    g = torch.Generator().manual_seed(2)
    vel, types = torch.randn(30, 2, 2, generator=g, dtype=torch.float64), torch.randint(0, 2, (30,), generator=g)
    bnd, edges = boundary_features(pos, torch.zeros(2), torch.full((2,), 10.0), 2.0), radius_graph(pos, 2.0)
    a = concat(vel, types, bnd, pos, edges, 2.0)
    b = split(vel, types, bnd, pos, edges, 2.0)
    torch.testing.assert_close(a, b, rtol=1e-12, atol=1e-12)
    a.sum().backward()
    b.sum().backward()
    for (name, p), q in zip(concat.named_parameters(), split.parameters(), strict=True):
        torch.testing.assert_close(p.grad, q.grad, rtol=1e-10, atol=1e-12, msg=name)
