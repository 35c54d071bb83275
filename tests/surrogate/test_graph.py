import numpy as np
import pytest
import torch

from surrogate.graph import radius_graph


def brute_force(x, r, kinematic=None):
    n = len(x)
    edges = set()
    for i in range(n):
        for j in range(n):
            if i == j:
                edges.add((i, i))
            elif np.linalg.norm(x[i] - x[j]) < r and not (kinematic is not None and kinematic[i] and kinematic[j]):
                edges.add((i, j))
    return edges


def as_set(edge_index):
    return set(map(tuple, edge_index.T.tolist()))


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_matches_brute_force(dim, seed):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0, 10, (80, dim))
    kin = rng.uniform(size=80) < 0.3
    assert as_set(radius_graph(x, 2.0)) == brute_force(x, 2.0)
    assert as_set(radius_graph(torch.tensor(x), 2.0, kinematic=kin)) == brute_force(x, 2.0, kin)


def test_both_directions_and_strict_radius():
    x = np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0]])
    edges = as_set(radius_graph(x, 1.0))             # distance exactly R: no edge (d < R)
    assert edges == {(0, 0), (1, 1), (2, 2)}
    edges = as_set(radius_graph(x, 1.5))
    assert (0, 1) in edges and (1, 0) in edges and (1, 2) not in edges


def test_isolated_and_empty_and_single():
    assert radius_graph(np.zeros((0, 2)), 1.0).shape == (2, 0)
    assert as_set(radius_graph(np.array([[5.0, 5.0]]), 1.0)) == {(0, 0)}
    x = np.array([[0.0, 0.0], [100.0, 100.0]])
    assert as_set(radius_graph(x, 1.0, self_loops=False)) == set()
