import numpy as np
import torch

from surrogate.simulator import Graph, LearnedSimulator, build_graph, prune_isolated, stack_graphs

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
    torch.testing.assert_close(nxt, 2 * g.window[-1] - g.window[-2] + physical)
    torch.testing.assert_close(sim.target(g.window, nxt), acc)


def test_step_never_predicts_kinematic_particles():
    sim = LearnedSimulator(STATS, MODEL).double()
    g = sample()
    supplied = torch.full((30, 2), -7.0, dtype=torch.float64)
    nxt = sim.step(g, supplied)
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
    unpruned = torch.where(kinematic.unsqueeze(-1), supplied, sim.integrate(window, sim(full)))
    torch.testing.assert_close(sim.step(full, supplied), unpruned, rtol=1e-12, atol=1e-12)
