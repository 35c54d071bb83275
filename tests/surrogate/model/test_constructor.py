import math

import pytest
import torch

from surrogate.graph import build_graph
from surrogate.model.constructor import EDGE_FEATURES, EdgeConstructor, edge_feature_width, edge_inputs
from surrogate.simulator import LearnedSimulator

ALL = list(EDGE_FEATURES)


def two_discs():
    """Sender 0 at the origin, receiver 1 at (3, 4): 5 m apart, radii 1 and 1.5, closing at 1 m per frame in x."""
    pos = torch.tensor([[0.0, 0.0], [3.0, 4.0]], dtype=torch.float64)
    velocity = torch.tensor([[0.5, 0.0], [-0.5, 0.0]], dtype=torch.float64)
    radii = torch.tensor([1.0, 1.5], dtype=torch.float64)
    return pos, torch.tensor([[0], [1]]), velocity, radii


def test_edge_inputs_are_eq7_then_the_optional_features_by_hand():
    pos, edges, velocity, radii = two_discs()
    r = 10.0
    plain = edge_inputs(pos, edges, r)
    torch.testing.assert_close(plain, torch.tensor([[0.3, 0.4, 0.5]], dtype=torch.float64))
    full = edge_inputs(pos, edges, r, ALL, velocity, radii)
    # relative velocity (-1, 0)/R; one frame on the pair is (2, 4) apart: sqrt(20)/R; gap (5 - 2.5)/R
    want = [0.3, 0.4, 0.5, -0.1, 0.0, math.sqrt(20.0) / r, 0.25]
    torch.testing.assert_close(full, torch.tensor([want], dtype=torch.float64))
    assert full.shape[1] == edge_feature_width(2, ALL) == 7
    # listed in another order, the inputs keep the order of EDGE_FEATURES
    torch.testing.assert_close(edge_inputs(pos, edges, r, ALL[::-1], velocity, radii), full)


def test_edge_inputs_do_not_change_under_a_common_shift_and_a_common_extra_velocity():
    g = torch.Generator().manual_seed(0)
    pos = torch.rand(12, 3, generator=g, dtype=torch.float64) * 5
    velocity = torch.randn(12, 3, generator=g, dtype=torch.float64)
    radii = torch.rand(12, generator=g, dtype=torch.float64) + 0.2
    edges = torch.randint(0, 12, (2, 30), generator=g)
    a = edge_inputs(pos, edges, 2.0, ALL, velocity, radii)
    b = edge_inputs(pos + torch.tensor([7.0, -3.0, 1.5], dtype=torch.float64), edges, 2.0, ALL,
                    velocity + torch.tensor([0.4, 0.2, -9.0], dtype=torch.float64), radii)
    torch.testing.assert_close(a, b, rtol=1e-12, atol=1e-12)


def test_an_unknown_or_repeated_edge_feature_is_refused_by_name():
    with pytest.raises(ValueError, match="unknown edge feature 'spin'.*allowed: relative_velocity, projected_distance"):
        EdgeConstructor(2, 8, 8, features=["spin"])
    with pytest.raises(ValueError, match="lists a feature twice"):
        EdgeConstructor(2, 8, 8, features=["gap", "gap"])
    pos, edges, _, _ = two_discs()
    with pytest.raises(ValueError, match="need the particles' velocity"):
        edge_inputs(pos, edges, 1.0, ["relative_velocity"])


def stats(radius_mean=2.0, radius_std=0.5):
    return {"dim": 2, "connectivity_radius": 3.0, "n_types": 2, "bounds": [[0.0, 20.0], [0.0, 20.0]],
            "velocity_mean": [0.0, 0.0], "velocity_std": [1.0, 1.0], "acceleration_mean": [0.0, 0.0],
            "acceleration_std": [1.0, 1.0],
            "property_stats": {"radius": {"mean": radius_mean, "std": radius_std, "log": False}}}


def model_cfg(**extra):
    return {"history": 2, "latent": 16, "hidden": 16, "message_passing": 2, "embed": 4, "mlp_layers": 3,
            "properties": ["radius"], **extra}


def test_the_gap_needs_the_radius_property_and_reads_the_radii_back_from_it():
    with pytest.raises(ValueError, match="gap needs the particle radius, so model.properties must list radius"):
        LearnedSimulator(stats(), {**model_cfg(edge_features=["gap"]), "properties": []})
    simulator = LearnedSimulator(stats(), model_cfg(edge_features=["gap"]))
    radii = torch.tensor([1.5, 2.0, 3.25])
    torch.testing.assert_close(simulator.radii(((radii - 2.0) / 0.5).unsqueeze(1)), radii)


def window_graph(velocity_scale):
    g = torch.Generator().manual_seed(3)
    last = torch.rand(10, 2, generator=g) * 6 + 7
    previous = last - velocity_scale * torch.randn(10, 2, generator=g)
    types = torch.ones(10, dtype=torch.long)
    kinematic = torch.zeros(10, dtype=torch.bool)
    props = torch.zeros(10, 1)
    return build_graph(torch.stack([previous, last]), types, kinematic, 3.0, props)


def test_velocity_edge_features_are_extra_inputs_of_the_edge_constructor_and_nothing_else():
    plain = LearnedSimulator(stats(), model_cfg())
    assert plain.model.edge_constructor.in_dim == 3 and plain.edge_features == ()
    extended = LearnedSimulator(stats(), model_cfg(edge_features=["relative_velocity", "projected_distance"]))
    assert extended.model.edge_constructor.in_dim == 6
    extra = sum(p.numel() for p in extended.parameters()) - sum(p.numel() for p in plain.parameters())
    assert extra == 3 * 16                      # three more inputs to the edge constructor's first layer only
    # the plain model's weights, with zero weight on the three extra inputs: the plain model's prediction
    state = plain.state_dict()
    first = "model.edge_constructor.mlp.0.weight"
    state[first] = torch.cat([state[first], torch.zeros(16, 3)], dim=1)
    extended.load_state_dict(state)
    graph = window_graph(0.2)
    torch.testing.assert_close(extended(graph), plain(graph), rtol=1e-6, atol=1e-6)
    with torch.no_grad():
        extended.model.edge_constructor.mlp[0].weight[:, 3:] = 0.5
    assert not torch.allclose(extended(graph), plain(graph), atol=1e-3)
