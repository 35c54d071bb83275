"""The neighbour cap (model.max_neighbours): each receiver keeps its N nearest senders within R, ties to the
lower sender index, self edge kept; what it drops is counted; no cap leaves the radius graph as it is."""

import numpy as np
import pytest
import torch

from surrogate.graph import build_graph, cap_neighbours, neighbour_edges, prune_isolated, radius_graph, stack_graphs
from surrogate.neighbours import Histogram, check_cap, neighbour_counts

METHODS = ["kdtree", "cells"]


def squared(x: np.ndarray, i: int, j: int) -> float:
    """|x_i - x_j|^2 summed axis by axis in x's dtype, as the graph measures it."""
    total = None
    for axis in range(x.shape[1]):
        gap = x[i, axis] - x[j, axis]
        total = gap * gap if total is None else total + gap * gap
    return total


def brute_force_capped(x: np.ndarray, r: float, cap: int, kinematic=None) -> tuple[set, int, int]:
    """Every receiver's ``cap`` nearest senders within r (ties: lower sender index) plus its self edge, the
    receivers with more than ``cap`` senders and the edges left out: one receiver at a time."""
    limit = np.asarray(r * r, dtype=x.dtype)
    edges, capped, dropped = set(), 0, 0
    for j in range(len(x)):
        senders = sorted((squared(x, i, j), i) for i in range(len(x))
                         if i != j and squared(x, i, j) < limit
                         and not (kinematic is not None and kinematic[i] and kinematic[j]))
        edges |= {(i, j) for _, i in senders[:cap]} | {(j, j)}
        if len(senders) > cap:
            capped, dropped = capped + 1, dropped + len(senders) - cap
    return edges, capped, dropped


def as_set(edge_index: torch.Tensor) -> set:
    return set(map(tuple, edge_index.T.tolist()))


def capped_graph(x, r, cap, kinematic=None, method="auto"):
    pos = torch.as_tensor(x)
    return cap_neighbours(radius_graph(pos, r, kinematic, method=method), pos, cap)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("cap", [1, 3, 8])
def test_the_capped_graph_is_the_n_nearest_within_r_of_brute_force(dim, seed, cap, method):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0, 6, (90, dim))
    kin = rng.uniform(size=90) < 0.3
    for kinematic in (None, kin):
        got = capped_graph(x, 2.0, cap, kinematic, method)
        want, capped, dropped = brute_force_capped(x, 2.0, cap, kinematic)
        assert as_set(got.edge_index) == want
        assert (got.capped_receivers, got.dropped_edges) == (capped, dropped) and dropped > 0


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_ties_go_to_the_lower_sender_on_a_lattice_with_duplicates(dim, dtype):
    """Integer points: many senders exactly as far apart, some points twice (distance 0), pairs exactly R apart."""
    rng = np.random.default_rng(dim)
    x = rng.integers(0, 5, (120, dim)).astype(dtype)
    for cap in (1, 2, 5):
        for method in METHODS:
            got = capped_graph(x, 2.0, cap, method=method)
            want, capped, dropped = brute_force_capped(x, 2.0, cap)
            assert as_set(got.edge_index) == want and (got.capped_receivers, got.dropped_edges) == (capped, dropped)


def test_the_cap_does_not_depend_on_the_edge_order():
    rng = np.random.default_rng(3)
    x = torch.tensor(rng.integers(0, 4, (60, 2)).astype(np.float64))
    edges = radius_graph(x, 1.5)
    shuffled = edges[:, torch.randperm(edges.shape[1], generator=torch.Generator().manual_seed(0))]
    a, b = cap_neighbours(edges, x, 2), cap_neighbours(shuffled, x, 2)
    assert as_set(a.edge_index) == as_set(b.edge_index) and a[1:] == b[1:]


def crafted() -> tuple[torch.Tensor, torch.Tensor]:
    """Moving A B C D at x = 0, 1, 2, 3 and kinematic K1 K2 at 4, 5 (y = 0), R = 1.5: every pair 1 apart is
    an edge but K1-K2 (two kinematic particles)."""
    x = torch.tensor([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0], [4.0, 0.0], [5.0, 0.0]])
    return x, torch.tensor([False, False, False, False, True, True])


def test_the_counts_of_a_crafted_case():
    """Senders: A {B}, B {A, C}, C {B, D}, D {C, K1}, K1 {D}, K2 {}. A cap of 1 caps B, C and D, one edge each,
    and keeps the lower index of each tie: B <- A, C <- B, D <- C."""
    x, kin = crafted()
    capped = neighbour_edges(x, 1.5, kin, 1)
    assert (capped.capped_receivers, capped.dropped_edges) == (3, 3)
    assert as_set(capped.edge_index) == {(0, 0), (1, 1), (2, 2), (3, 3), (4, 4), (5, 5),
                                         (1, 0), (0, 1), (1, 2), (2, 3), (3, 4)}
    assert neighbour_edges(x, 1.5, kin, 2)[1:] == (0, 0)
    np.testing.assert_array_equal(neighbour_counts(x.numpy(), 1.5, kin.numpy()), [1, 2, 2, 2, 1, 0])
    histogram = Histogram.of(neighbour_counts(x.numpy(), 1.5, kin.numpy()))
    summary = histogram.summary(1)
    assert summary == {"receivers": 6, "max": 2, "p99": 2, "mean": pytest.approx(8 / 6), "histogram": [1, 2, 3],
                       "max_neighbours": 1, "capped_receiver_fraction": 0.5, "dropped_edge_fraction": 3 / 8}
    assert histogram.summary()["capped_receiver_fraction"] is None and histogram.percentile(50) == 1


def test_the_graphs_counts_survive_pruning_and_batching():
    x, kin = crafted()
    window = torch.stack([x - 0.1, x])
    graph = build_graph(window, torch.zeros(6, dtype=torch.long), kin, 1.5, max_neighbours=1)
    assert (graph.capped_receivers, graph.dropped_edges) == (3, 3)
    reduced, _ = prune_isolated(graph)                  # K2 has no edge left: pruned, the counts stay
    assert reduced.types.numel() == 5 and (reduced.capped_receivers, reduced.dropped_edges) == (3, 3)
    both = stack_graphs([graph, graph])
    assert (both.capped_receivers, both.dropped_edges) == (6, 6)


@pytest.mark.parametrize("dim", [2, 3])
def test_no_cap_is_the_radius_graph_bit_for_bit(dim):
    rng = np.random.default_rng(dim)
    x = torch.tensor(rng.uniform(0, 8, (150, dim)), dtype=torch.float32)
    kin = torch.tensor(rng.uniform(size=150) < 0.3)
    plain = radius_graph(x, 1.7, kin)
    window = torch.stack([x, x])
    graph = build_graph(window, torch.zeros(150, dtype=torch.long), kin, 1.7)
    assert torch.equal(graph.edge_index, plain) and (graph.capped_receivers, graph.dropped_edges) == (0, 0)
    assert torch.equal(build_graph(window, graph.types, kin, 1.7, max_neighbours=None).edge_index, plain)
    # a cap no receiver reaches returns the graph as given
    most = int(torch.bincount(plain[1][plain[0] != plain[1]], minlength=150).max())
    untouched = cap_neighbours(plain, x, most)
    assert untouched.edge_index is plain and untouched[1:] == (0, 0)
    assert cap_neighbours(plain, x, most - 1).dropped_edges > 0


def test_the_numpy_counts_are_the_graphs_in_degrees():
    rng = np.random.default_rng(5)
    x = rng.uniform(0, 10, (300, 3)).astype(np.float32)
    kin = rng.uniform(size=300) < 0.4
    edges = radius_graph(torch.from_numpy(x), 2.2, kin)
    degree = torch.bincount(edges[1][edges[0] != edges[1]], minlength=300).numpy()
    np.testing.assert_array_equal(neighbour_counts(x, 2.2, kin), degree)


@pytest.mark.parametrize("bad", [0, -3, 2.5, "8", True])
def test_a_cap_that_is_not_a_positive_integer_is_refused_by_name(bad):
    with pytest.raises(ValueError, match=r"model.max_neighbours = .*: null \(no cap\) or an integer >= 1"):
        check_cap(bad)
    x, _ = crafted()
    with pytest.raises(ValueError, match="model.max_neighbours"):
        cap_neighbours(radius_graph(x, 1.5), x, bad)
