"""Neighbour graphs for Graph-DEM (article 4.2.2), on the positions' device.

PyG's ``radius_graph`` needs pyg-lib or torch-cluster; we build the same graph ourselves: a directed
edge (sender i -> receiver j) for every pair closer than R, in both directions, plus a self edge on
every node. Closer than R means strictly: the squared distance, summed over the axes in the
positions' dtype, below R^2 rounded to that dtype (no square root: torch's and NumPy's roundings
of it differ). Pairs of two kinematic
particles get no edge (their interaction never changes a prediction). The result is ``edge_index``
[2, E] int64 on the positions' device; the edge order is unspecified.

Two implementations give identical edge sets (tests):
- ``"kdtree"``: scipy's cKDTree on the CPU (NumPy), edges copied to the positions' device;
- ``"cells"``: a cell list in torch, on the positions' device: particles binned into cells of side
  >= R, sorted by cell, and for each of the (3^D + 1)/2 cell offsets that see each pair once the
  candidates found with ``searchsorted`` and kept where closer than R. Vectorised over particles,
  its memory is the edges plus about ``CANDIDATE_CHUNK`` candidate pairs at a time.

Rule (``method="auto"``): the cell list for tensors on any device but the CPU, the k-d tree on the
CPU, where it was faster at every measured size from 700 to 200 000 particles in 2D and 3D
(docs/surrogate.md, ``python -m surrogate.bench_graph``). ``method`` forces either one.
"""

from __future__ import annotations

import itertools
import math
from typing import Literal

import numpy as np
import torch
from scipy.spatial import cKDTree

Method = Literal["auto", "kdtree", "cells"]
CANDIDATE_CHUNK = 1 << 22      # candidate pairs checked at once by the cell list (bounds its working memory)


def radius_graph(pos: torch.Tensor | np.ndarray, radius: float,
                 kinematic: torch.Tensor | np.ndarray | None = None, self_loops: bool = True,
                 *, method: Method = "auto") -> torch.Tensor:
    """``edge_index`` [2, E] (row 0 senders, row 1 receivers) of all pairs with distance < radius,
    on ``pos``'s device; ``method`` as the module docstring says."""
    x = pos if isinstance(pos, torch.Tensor) else torch.from_numpy(np.asarray(pos))
    x = x.detach()
    if method == "auto":
        method = choose_method(x)
    if method == "kdtree":
        pairs = kdtree_pairs(x, radius)
    elif method == "cells":
        pairs = cell_list_pairs(x, radius)
    else:
        raise ValueError(f"unknown radius graph method {method!r}: auto, kdtree or cells")
    if kinematic is not None:
        kin = torch.as_tensor(kinematic, dtype=torch.bool).to(x.device)
        pairs = pairs[:, ~(kin.index_select(0, pairs[0]) & kin.index_select(0, pairs[1]))]
    return both_ways(pairs, len(x), self_loops)


def choose_method(pos: torch.Tensor) -> Method:
    """The measured rule: the k-d tree for CPU tensors, the cell list on any other device."""
    return "kdtree" if pos.device.type == "cpu" else "cells"


def both_ways(pairs: torch.Tensor, n: int, self_loops: bool) -> torch.Tensor:
    """[2, 2P (+ n)] edges from [2, P] unordered pairs: both directions, then the self edges."""
    loops = [torch.arange(n, device=pairs.device)] if self_loops else []
    edges = torch.empty((2, 2 * pairs.shape[1] + len(loops) * n), dtype=torch.int64, device=pairs.device)
    torch.cat([pairs[0], pairs[1], *loops], out=edges[0])
    torch.cat([pairs[1], pairs[0], *loops], out=edges[1])
    return edges


def kdtree_pairs(pos: torch.Tensor, radius: float) -> torch.Tensor:
    """[2, P] pairs (i < j) closer than radius, found by scipy's cKDTree on the CPU."""
    x = pos.cpu().numpy()
    if len(x) < 2:
        return torch.empty((2, 0), dtype=torch.int64, device=pos.device)
    # the tree measures in float64: a little beyond R, so that the strict test below decides
    pairs = cKDTree(x).query_pairs(radius * (1 + 1e-6), output_type="ndarray")
    squared = ((x[pairs[:, 0]] - x[pairs[:, 1]]) ** 2).sum(axis=1)
    pairs = pairs[squared < np.asarray(radius * radius, dtype=x.dtype)]
    return torch.from_numpy(pairs.T.astype(np.int64)).to(pos.device)


def cell_list_pairs(pos: torch.Tensor, radius: float, chunk: int = CANDIDATE_CHUNK) -> torch.Tensor:
    """[2, P] pairs closer than radius, each unordered pair once, by a cell list on pos's device."""
    n, dim = pos.shape
    if n < 2:
        return torch.empty((2, 0), dtype=torch.int64, device=pos.device)
    if not bool(torch.isfinite(pos).all()):
        raise ValueError("radius_graph: positions must be finite")
    cells = cell_coordinates(pos, radius)
    strides = cell_strides(cells)
    key, order = torch.sort((cells * strides).sum(dim=1))
    near = pos.index_select(0, order).T.contiguous()    # [D, N] in cell order: a cell's particles are a range
    cell_key, count = torch.unique_consecutive(key, return_counts=True)
    end = count.cumsum(0)
    start = end - count
    own = torch.repeat_interleave(torch.arange(len(count), device=pos.device), count, output_size=n)
    found = []
    for offset in half_offsets(dim):
        if any(offset):                                 # a neighbour cell: all its particles, if it has any
            shifted = cell_key + int(np.dot(offset, strides.tolist()))
            slot = torch.searchsorted(cell_key, shifted).clamp_(max=len(cell_key) - 1)
            length = torch.where(cell_key.index_select(0, slot) == shifted, count.index_select(0, slot), 0)
            begin, length = start.index_select(0, slot).index_select(0, own), length.index_select(0, own)
        else:                                           # the own cell: only the particles after this one
            begin = torch.arange(1, n + 1, device=pos.device)
            length = end.index_select(0, own) - begin
        for lo, hi in chunk_bounds(length, chunk):
            i, j = expand_ranges(lo, begin[lo:hi], length[lo:hi])
            close = (squared_distance(near, i, j) < radius * radius).nonzero().squeeze(1)
            pair = torch.stack([i.index_select(0, close), j.index_select(0, close)])
            found.append(order.index_select(0, pair.flatten()).view(2, -1))
    return torch.cat(found, dim=1)


def squared_distance(axes: torch.Tensor, i: torch.Tensor, j: torch.Tensor) -> torch.Tensor:
    """|p_i - p_j|^2 from [D, N] coordinates, summed axis by axis as NumPy sums a row (same rounding)."""
    total = None
    for axis in axes:
        gap = axis.index_select(0, i).sub_(axis.index_select(0, j))
        gap.mul_(gap)
        total = gap if total is None else total.add_(gap)
    return total


def cell_coordinates(pos: torch.Tensor, radius: float) -> torch.Tensor:
    """[N, D] int64 cell coordinates (cells of side >= R), >= 1, each axis compressed: occupied
    neighbouring cells stay 1 apart, larger gaps become 2, so far-apart particles cannot overflow."""
    exact = torch.float32 if pos.device.type == "mps" else torch.float64    # MPS has no float64
    x = pos.to(exact)
    low = x.amin(dim=0)
    span = float((x.amax(dim=0) - low).max())
    # cells a little wider than R: no rounding of the binning or the distance hides a pair
    margin = 8 * torch.finfo(pos.dtype).eps + 8 * torch.finfo(exact).eps * (span / radius + 1)
    bins = torch.floor((x - low) / (radius * (1 + margin)))
    coords = torch.empty(bins.shape, dtype=torch.int64, device=pos.device)
    for axis in range(bins.shape[1]):
        values, inverse = torch.unique(bins[:, axis], return_inverse=True)
        steps = torch.where(values.diff() > 1, 2, 1)
        coords[:, axis] = torch.cat([steps.new_zeros(1), steps.cumsum(0)])[inverse] + 1
    return coords


def cell_strides(cells: torch.Tensor) -> torch.Tensor:
    """Strides [D] of a row-major cell key with a free cell on every side (no offset wraps)."""
    extent = [int(e) + 2 for e in cells.amax(dim=0).tolist()]
    if math.prod(extent) >= 2**62:
        raise ValueError(f"radius_graph: {extent} cells per axis overflow an int64 key; use method='kdtree'")
    strides = [math.prod(extent[axis + 1:]) for axis in range(len(extent))]
    return torch.tensor(strides, dtype=torch.int64, device=cells.device)


def half_offsets(dim: int) -> list[tuple[int, ...]]:
    """The zero offset and the (3^D - 1)/2 lexicographically positive ones: every pair of
    neighbouring cells seen once."""
    return [o for o in itertools.product((-1, 0, 1), repeat=dim) if o >= (0,) * dim]


def chunk_bounds(n_cand: torch.Tensor, chunk: int) -> list[tuple[int, int]]:
    """Consecutive particle ranges [lo, hi) with about ``chunk`` candidates each (at least one particle)."""
    total = n_cand.cumsum(0)
    n_chunks = max(1, math.ceil(int(total[-1]) / chunk))
    cuts = torch.searchsorted(total, torch.arange(1, n_chunks, device=total.device) * chunk, right=True)
    bounds = sorted({0, len(n_cand), *(int(c) + 1 for c in cuts.tolist())})
    return [(lo, hi) for lo, hi in itertools.pairwise(bounds) if lo < hi]


def expand_ranges(first: int, begin: torch.Tensor, length: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Rows and columns of the pairs (first + k, begin[k] + m) for m in range(length[k]), vectorised."""
    total = int(length.sum())
    row = torch.repeat_interleave(torch.arange(len(length), device=length.device), length, output_size=total)
    shift = begin - (length.cumsum(0) - length)        # column = shift[row] + position in the flat list
    return row + first, shift.index_select(0, row) + torch.arange(total, device=length.device)
