import json

import numpy as np
import pytest
import torch

from generators import h5md
from surrogate.graph import CPU_CELLS_FROM, cell_list_pairs, choose_method, choose_split, kdtree_pairs, radius_graph

METHODS = ["kdtree", "cells"]


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


def cdist_edges(x: torch.Tensor, r: float, kinematic: torch.Tensor | None = None) -> set:
    """All pairs closer than r both ways plus self edges, from the full distance matrix."""
    close = torch.cdist(x, x, compute_mode="donot_use_mm_for_euclid_dist") < r
    if kinematic is not None:
        close &= ~(kinematic[:, None] & kinematic[None, :])
    close |= torch.eye(len(x), dtype=torch.bool)
    return set(map(tuple, close.nonzero().tolist()))


def as_set(edge_index):
    return set(map(tuple, edge_index.T.tolist()))


def unordered(pairs):
    return as_set(pairs.sort(dim=0).values)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_matches_brute_force(dim, seed, method):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0, 10, (80, dim))
    kin = rng.uniform(size=80) < 0.3
    assert as_set(radius_graph(x, 2.0, method=method)) == brute_force(x, 2.0)
    assert as_set(radius_graph(torch.tensor(x), 2.0, kinematic=kin, method=method)) == brute_force(x, 2.0, kin)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_random_clouds_with_duplicates_and_exact_distances_match_cdist(dim, dtype, method):
    gen = torch.Generator().manual_seed(dim)
    cloud = torch.rand(600, dim, generator=gen, dtype=dtype) * 30 - 20          # negative coordinates too
    lattice = torch.randint(-8, 8, (300, dim), generator=gen).to(dtype) * 0.5   # many pairs exactly at R = 1
    x = torch.cat([cloud, lattice, cloud[:50], lattice[:50]])                    # and duplicates
    kin = torch.rand(len(x), generator=gen) < 0.4
    for r in (1.0, 2.5):
        edges = radius_graph(x, r, kinematic=kin, method=method)
        assert as_set(edges) == cdist_edges(x, r, kin)
        assert edges.shape[1] == len(as_set(edges))                              # no edge twice
    assert as_set(radius_graph(x, 1.0, self_loops=False, method=method)) == cdist_edges(x, 1.0) - {
        (i, i) for i in range(len(x))}


@pytest.mark.parametrize("method", METHODS)
def test_both_directions_and_strict_radius(method):
    x = np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0]])
    edges = as_set(radius_graph(x, 1.0, method=method))   # distance exactly R: no edge (d < R)
    assert edges == {(0, 0), (1, 1), (2, 2)}
    edges = as_set(radius_graph(x, 1.5, method=method))
    assert (0, 1) in edges and (1, 0) in edges and (1, 2) not in edges


@pytest.mark.parametrize("method", METHODS)
def test_isolated_and_empty_and_single(method):
    assert radius_graph(np.zeros((0, 2)), 1.0, method=method).shape == (2, 0)
    assert as_set(radius_graph(np.array([[5.0, 5.0]]), 1.0, method=method)) == {(0, 0)}
    x = np.array([[0.0, 0.0], [100.0, 100.0]])
    assert as_set(radius_graph(x, 1.0, self_loops=False, method=method)) == set()
    grid = np.array([[0, 0], [1, 1], [3, 3]])                # integer positions: R is not rounded to an integer
    assert as_set(radius_graph(grid, 1.5, self_loops=False, method=method)) == {(0, 1), (1, 0)}


@pytest.mark.parametrize("dim", [2, 3])
def test_cell_list_far_apart_clusters_every_cell_size_and_small_chunks(dim):
    gen = torch.Generator().manual_seed(0)
    blob = torch.rand(200, dim, generator=gen, dtype=torch.float64) * 3
    lattice = torch.randint(0, 6, (100, dim), generator=gen).double() * 0.35     # exact distances 0.7
    x = torch.cat([blob - 1e9, blob, blob + 1e9, blob * 1e-3 + 5e8, lattice, lattice[:20]])
    expected = unordered(kdtree_pairs(x, 0.7))
    for split in (1, 2, 3, 4):
        pairs = cell_list_pairs(x, 0.7, split=split)
        assert unordered(pairs) == expected and pairs.shape[1] == len(expected)
    assert unordered(cell_list_pairs(x, 0.7, split=2, chunk=300)) == expected


def test_cell_size_follows_density():
    sparse, dense = torch.rand(100, 2) * 100, torch.rand(10_000, 3)
    assert choose_split(sparse, 1.0) == 1 and choose_split(dense, 0.1) == 2 and choose_split(dense, 1.0) == 4


def test_cell_list_refuses_non_finite_positions():
    with pytest.raises(ValueError, match="finite"):
        radius_graph(torch.tensor([[0.0, 0.0], [float("nan"), 1.0]]), 1.0, method="cells")


def test_output_device_and_dispatch():
    x = torch.rand(50, 3)
    for method in METHODS:
        edges = radius_graph(x, 0.3, method=method)
        assert edges.device == x.device and edges.dtype == torch.int64
    assert choose_method(x) == "kdtree" and choose_method(torch.empty(CPU_CELLS_FROM, 3)) == "cells"
    meta = torch.empty(1, 3, device="meta")                # no data on meta: only the sizes that need none
    assert choose_method(meta) == "cells"
    for n in (0, 1):
        edges = radius_graph(torch.empty(n, 3, device="meta"), 0.3)
        assert edges.device.type == "meta" and edges.shape == (2, n) and edges.dtype == torch.int64
    with pytest.raises(ValueError, match="method"):
        radius_graph(x, 0.3, method="octree")


@pytest.mark.engine
def test_cell_list_equals_kdtree_on_real_slide_frames(tiny_dataset):
    radius = json.loads(tiny_dataset["stats_json"])["connectivity_radius"]
    for path in tiny_dataset["split_table"]["path"][:2]:
        traj = h5md.read(path)
        for t in (0, traj.n_frames // 2, traj.n_frames - 1):
            pos = torch.from_numpy(traj.position[t])
            for kin in (None, traj.kinematic):
                kd = radius_graph(pos, radius, kin, method="kdtree")
                cells = radius_graph(pos, radius, kin, method="cells")
                assert kd.shape == cells.shape and as_set(kd) == as_set(cells)
