import numpy as np
import torch

from surrogate.graph import Graph, build_graph, prune_isolated, stack_graphs
from surrogate.simulator import LearnedSimulator

STATS = {"dim": 2, "bounds": [[0.0, 1000.0], [0.0, 1000.0]], "connectivity_radius": 3.0, "n_types": 2,
         "velocity_mean": [0.1, -0.2], "velocity_std": [0.5, 0.4],
         "acceleration_mean": [0.01, -0.02], "acceleration_std": [0.05, 0.04]}
MODEL = {"history": 4, "latent": 16, "hidden": 16, "message_passing": 2, "embed": 4, "mlp_layers": 3,
         "properties": []}


def sample(offset=(0.0, 0.0), seed=0):
    rng = np.random.default_rng(seed)
    p = rng.uniform(400, 415, (30, 2)) + np.cumsum(rng.normal(0, 0.1, (4, 30, 2)), axis=0)
    window = torch.tensor(p + np.asarray(offset), dtype=torch.float64)
    types = torch.tensor(rng.integers(0, 2, 30))
    kinematic = torch.tensor(rng.uniform(size=30) < 0.2)
    return build_graph(window, types, kinematic, STATS["connectivity_radius"])


def test_prediction_invariant_to_translating_every_particle_away_from_boundaries():
    torch.manual_seed(0)
    sim = LearnedSimulator(STATS, MODEL).double()
    a, b = sample(), sample(offset=(137.25, -61.5))
    assert torch.equal(a.edge_index, b.edge_index)
    torch.testing.assert_close(sim(a), sim(b), rtol=1e-9, atol=1e-9)


def test_integration_is_eq_1_and_target_inverts_it():
    sim = LearnedSimulator(STATS, MODEL).double()
    g = sample()
    acc = torch.randn(30, 2, dtype=torch.float64)
    nxt = sim.integrate(g.window, acc)
    physical = acc * sim.acceleration_std + sim.acceleration_mean
    assert nxt.shape == (1, 30, 2)                        # one frame per call: a bundle of one
    torch.testing.assert_close(nxt[0], 2 * g.window[-1] - g.window[-2] + physical)
    torch.testing.assert_close(sim.target(g.window, nxt), acc)
    torch.testing.assert_close(sim.target(g.window, nxt[0]), acc)      # one frame may come without its axis


def test_step_never_predicts_kinematic_particles():
    sim = LearnedSimulator(STATS, MODEL).double()
    g = sample()
    supplied = torch.full((30, 2), -7.0, dtype=torch.float64)
    nxt = sim.step(g, supplied)[0]
    assert torch.all(nxt[g.kinematic] == -7.0) and torch.all(nxt[~g.kinematic] != -7.0)


def test_a_batch_is_the_disjoint_union_of_its_samples():
    torch.manual_seed(0)
    sim = LearnedSimulator(STATS, MODEL).double()
    a, b = sample(seed=1), sample(seed=2)
    both = stack_graphs([a, b])
    assert isinstance(both, Graph) and both.edge_index.shape[1] == a.edge_index.shape[1] + b.edge_index.shape[1]
    torch.testing.assert_close(sim(both), torch.cat([sim(a), sim(b)]))


def test_pruning_drops_only_unlinked_kinematic_particles_and_changes_no_prediction():
    torch.manual_seed(0)
    sim = LearnedSimulator(STATS, MODEL).double()
    g = sample()
    far = torch.tensor([[800.0, 800.0], [805.0, 800.0], [20.0, 900.0]], dtype=torch.float64)   # walls far away
    window = torch.cat([g.window, far.expand(4, 3, 2)], dim=1)
    types = torch.cat([g.types, torch.zeros(3, dtype=torch.long)])
    kinematic = torch.cat([g.kinematic, torch.ones(3, dtype=torch.bool)])
    full = build_graph(window, types, kinematic, STATS["connectivity_radius"])
    reduced, index = prune_isolated(full)
    dropped = sorted(set(range(33)) - set(index.tolist()))
    assert {30, 31, 32} <= set(dropped)                   # 800/805 are 5 m apart: two walls, no edge between
    for i in dropped:                                     # only kinematic particles with nothing but a self edge
        assert kinematic[i] and int((full.edge_index == i).any(dim=0).sum()) == 1
    assert torch.equal(index[~reduced.kinematic], (~kinematic).nonzero().squeeze(1))
    moving = (~reduced.kinematic).nonzero().squeeze(1)
    torch.testing.assert_close(sim(reduced, decode=moving), sim(full)[~kinematic], rtol=1e-12, atol=1e-12)
    supplied = window[-1] + 1.0
    unpruned = torch.where(kinematic.unsqueeze(-1), supplied, sim.integrate(window, sim(full)))[0]
    torch.testing.assert_close(sim.step(full, supplied)[0], unpruned, rtol=1e-12, atol=1e-12)


def test_a_bundle_integrates_eq_1_frame_after_frame_and_target_inverts_it():
    """Three frames per call: frame b's acceleration in columns 2b..2b+1, each frame from the two before it."""
    sim = LearnedSimulator(STATS, {**MODEL, "bundle": 3}).double()
    g = sample()
    acc = torch.randn(30, 6, dtype=torch.float64)
    frames = sim.integrate(g.window, acc)
    assert frames.shape == (3, 30, 2)
    path = [g.window[-2], g.window[-1]]
    for b in range(3):
        physical = acc[:, 2 * b:2 * b + 2] * sim.acceleration_std + sim.acceleration_mean
        path.append(2 * path[-1] - path[-2] + physical)
        torch.testing.assert_close(frames[b], path[-1])
    torch.testing.assert_close(sim.target(g.window, frames), acc)
    assert sim(g).shape == (30, 6)


def test_a_bundled_step_keeps_every_frame_of_the_kinematic_particles():
    sim = LearnedSimulator(STATS, {**MODEL, "bundle": 2}).double()
    g = sample()
    supplied = torch.stack([torch.full((30, 2), -7.0), torch.full((30, 2), -8.0)]).double()
    frames = sim.step(g, supplied)
    assert frames.shape == (2, 30, 2)
    assert torch.all(frames[0, g.kinematic] == -7.0) and torch.all(frames[1, g.kinematic] == -8.0)
    torch.testing.assert_close(frames[:, ~g.kinematic], sim.integrate(g.window, sim(g))[:, ~g.kinematic])


def test_a_bundle_of_one_is_the_article_model_bit_for_bit():
    """bundle: 1 builds the same network from the same seed and predicts the same numbers as no bundle key."""
    torch.manual_seed(3)
    plain = LearnedSimulator(STATS, MODEL).double()
    torch.manual_seed(3)
    one = LearnedSimulator(STATS, {**MODEL, "bundle": 1}).double()
    g = sample()
    assert torch.equal(plain(g), one(g))


def test_a_bad_bundle_is_refused_by_name():
    for bad in (0, -2, 1.5, True, "2"):
        try:
            LearnedSimulator(STATS, {**MODEL, "bundle": bad})
        except ValueError as exc:
            assert "model.bundle" in str(exc) and "integer >= 1" in str(exc)
        else:
            raise AssertionError(f"bundle {bad!r} was accepted")
    sim = LearnedSimulator(STATS, {**MODEL, "bundle": 2}).double()
    g = sample()
    try:
        sim.target(g.window, g.window[-1])
    except ValueError as exc:
        assert "2 frame(s) per call" in str(exc)
    else:
        raise AssertionError("a one-frame target was accepted by a two-frame model")
