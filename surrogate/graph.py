"""Neighbour graphs for Graph-DEM (article 4.2.2), on the positions' device.

PyG's ``radius_graph`` needs pyg-lib or torch-cluster; we build the same graph ourselves: a directed
edge (sender i -> receiver j) for every pair closer than R, in both directions, plus a self edge on
every node; pairs of two kinematic particles get no edge (their interaction never changes a
prediction). Closer than R is strict: the squared distance, summed axis by axis in the positions'
dtype, below R^2 rounded to that dtype (no square root: torch's and NumPy's roundings of it differ).
The result is ``edge_index`` [2, E] int64 on the positions' device; the edge order is unspecified.

Two implementations give the same edge set (tests):
- ``"kdtree"``: scipy's cKDTree on the CPU (NumPy); the edges are copied to the positions' device.
- ``"cells"``: a cell list in torch on the positions' device. Particles are binned into cells of
  side R/k (k = 1-4 from the density, ``choose_split``) and sorted by row-major cell key, so the
  2k + 1 cells along the last axis around a cell are one range of particles; the
  ((2k + 1)^(D-1) + 1)/2 such strips that see every pair once (2 in 2D, 5 in 3D at k = 1) give
  candidate ranges by ``searchsorted``, kept where closer than R. Vectorised over particles (a
  Python loop over strips and chunks only); working memory: the edges plus ``CANDIDATE_CHUNK``
  candidates at a time.

Rule (``method="auto"``, ``choose_method``): the cell list on every device but the CPU; on the CPU
the k-d tree below ``CPU_CELLS_FROM`` particles and the cell list from there. Measured on one CPU
thread (``python -m evaluation.timing.graph``, table in docs/surrogate.md): the k-d tree is 1.6-2x
faster at 700 particles and up to 1.4x at 2 000, the two trade places around 6 000, and from
20 000 the cell list was 6-39 % faster in every run. ``method`` forces either one.

A neighbour cap (model config ``max_neighbours`` = N; null: none), :func:`cap_neighbours`: each receiver
keeps its N nearest senders of the radius graph, by the same squared distance, ties broken by the lower
sender index, and its self edge (not counted). The edges it drops and the receivers it caps are
counted and returned, never dropped silently. Without a cap the graph is the radius graph unchanged.

The model's input, :class:`Graph`: one sample's window of positions with its types, kinematic mask, properties
and the edges of its last frame (:func:`build_graph`), several samples stacked as one disjoint graph
(:func:`stack_graphs`), or the graph without the unpredicted particles no edge reaches (:func:`prune_isolated`).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np
import torch

from surrogate.neighbours import check_cap, close_pairs

Method = Literal["auto", "kdtree", "cells"]
CANDIDATE_CHUNK = 1 << 22      # candidate pairs checked at once by the cell list (bounds its working memory)
CPU_CELLS_FROM = 20_000        # particles from which the cell list builds CPU graphs (module docstring)


def radius_graph(pos: torch.Tensor | np.ndarray, radius: float,
                 kinematic: torch.Tensor | np.ndarray | None = None, self_loops: bool = True,
                 *, method: Method = "auto") -> torch.Tensor:
    """``edge_index`` [2, E] (row 0 senders, row 1 receivers) of all pairs with distance < radius,
    on ``pos``'s device; ``method`` as the module docstring says."""
    pairs = radius_pairs(pos, radius, kinematic, method=method)
    return both_ways(pairs, len(pos), self_loops)


def radius_pairs(pos: torch.Tensor | np.ndarray, radius: float, kinematic: torch.Tensor | np.ndarray | None = None,
                 *, method: Method = "auto") -> torch.Tensor:
    """[2, P] the pairs of the radius graph, each unordered pair once (no direction, no self edge), on
    ``pos``'s device."""
    x = pos if isinstance(pos, torch.Tensor) else torch.from_numpy(np.asarray(pos))
    x = x.detach() if x.is_floating_point() else x.double()
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
    return pairs


class CappedEdges(NamedTuple):
    """A graph after the neighbour cap: its edges, the receivers that had more senders than the cap, and
    the edges dropped."""

    edge_index: torch.Tensor
    capped_receivers: int
    dropped_edges: int


def cap_neighbours(edge_index: torch.Tensor, pos: torch.Tensor, max_neighbours: int) -> CappedEdges:
    """``edge_index`` [2, E] (senders, receivers) with each receiver's senders other than itself cut to its
    ``max_neighbours`` nearest by the squared distance of ``pos`` [N, D] (summed axis by axis in pos's
    dtype, as the radius graph measures), ties broken by the lower sender index; self edges are always
    kept. The kept edges stay in their order; a graph without a receiver over the cap is returned as given."""
    cap = check_cap(max_neighbours)
    sender, receiver = edge_index
    other = sender != receiver
    counts = torch.bincount(receiver[other], minlength=len(pos))
    over = counts > cap
    if not bool(over.any()):
        return CappedEdges(edge_index, 0, 0)
    candidate = (other & over.index_select(0, receiver)).nonzero().squeeze(1)
    s, r = sender.index_select(0, candidate), receiver.index_select(0, candidate)
    squared = squared_distance(pos.detach().T.contiguous(), s, r)
    # order by (receiver, squared distance, sender): stable sorts from the last key to the first
    order = torch.argsort(s, stable=True)
    order = order.index_select(0, torch.argsort(squared.index_select(0, order), stable=True))
    order = order.index_select(0, torch.argsort(r.index_select(0, order), stable=True))
    ranked = r.index_select(0, order)
    rank = torch.arange(len(ranked), device=ranked.device) - torch.searchsorted(ranked, ranked)
    dropped = candidate.index_select(0, order[rank >= cap])
    keep = torch.ones(edge_index.shape[1], dtype=torch.bool, device=edge_index.device)
    keep[dropped] = False
    return CappedEdges(edge_index[:, keep], int(over.sum()), int(dropped.numel()))


def choose_method(pos: torch.Tensor) -> Method:
    """The measured rule: the cell list off the CPU and for ``CPU_CELLS_FROM`` particles or more."""
    return "cells" if pos.device.type != "cpu" or len(pos) >= CPU_CELLS_FROM else "kdtree"


def both_ways(pairs: torch.Tensor, n: int, self_loops: bool) -> torch.Tensor:
    """[2, 2P (+ n)] edges from [2, P] unordered pairs: both directions, then the self edges."""
    loops = [torch.arange(n, device=pairs.device)] if self_loops else []
    edges = torch.empty((2, 2 * pairs.shape[1] + len(loops) * n), dtype=torch.int64, device=pairs.device)
    torch.cat([pairs[0], pairs[1], *loops], out=edges[0])
    torch.cat([pairs[1], pairs[0], *loops], out=edges[1])
    return edges


def kdtree_pairs(pos: torch.Tensor, radius: float) -> torch.Tensor:
    """[2, P] pairs (i < j) closer than radius, found by scipy's cKDTree on the CPU
    (:func:`surrogate.neighbours.close_pairs`)."""
    pairs = close_pairs(pos.cpu().numpy(), radius)
    return torch.from_numpy(pairs.T.astype(np.int64)).to(pos.device)


def cell_list_pairs(pos: torch.Tensor, radius: float, split: int | None = None,
                    chunk: int = CANDIDATE_CHUNK) -> torch.Tensor:
    """[2, P] pairs closer than radius, each unordered pair once, by a cell list on pos's device
    (cells of side R / ``split``, by default ``choose_split``)."""
    n, dim = pos.shape
    if n < 2:
        return torch.empty((2, 0), dtype=torch.int64, device=pos.device)
    if not bool(torch.isfinite(pos).all()):
        raise ValueError("radius_graph: positions must be finite")
    split = split or choose_split(pos, radius)
    cells = cell_coordinates(pos, radius, split)
    strides = cell_strides(cells, split)
    key, order = torch.sort((cells * strides).sum(dim=1))
    near = pos.index_select(0, order).T.contiguous()    # [D, N] in cell order: a cell's particles are a range
    cell_key, own = torch.unique_consecutive(key, return_inverse=True)
    found = []
    for offset in strip_offsets(dim, split):
        # a strip: 2 split + 1 cells consecutive along the last axis, so in key, hence one range of particles
        centre = cell_key + int(np.dot(offset, strides.tolist()))
        end = torch.searchsorted(key, centre + split, right=True).index_select(0, own)
        if any(offset):
            begin = torch.searchsorted(key, centre - split).index_select(0, own)
        else:                                           # the own strip: only the particles after this one
            begin = torch.arange(1, n + 1, device=pos.device)
        length = end - begin
        for lo, hi in chunk_bounds(length, chunk):
            i, j = expand_ranges(lo, begin[lo:hi], length[lo:hi])
            close = (squared_distance(near, i, j) < radius * radius).nonzero().squeeze(1)
            pair = torch.stack([i.index_select(0, close), j.index_select(0, close)])
            found.append(order.index_select(0, pair.flatten()).view(2, -1))
    return torch.cat(found, dim=1)


def choose_split(pos: torch.Tensor, radius: float, most: int = 4) -> int:
    """Cells per R: about one particle per cell at the bounding box's mean density, 1 to ``most``.

    Smaller cells test fewer candidates (per pair found, 2 instead of 2.9 in 2D, 3.7 instead of 6.4
    in 3D from R to R/2) but take more strips; on the CPU this count was the fastest or close
    (``python -m evaluation.timing.graph``). A box with empty regions only underestimates it.
    """
    n, dim = pos.shape
    box = (pos.amax(dim=0) - pos.amin(dim=0)).clamp(min=radius)
    per_cell = n / math.prod((box / radius).tolist())          # particles in an R^D cell
    return int(min(most, max(1, math.floor(per_cell ** (1 / dim) + 1e-9))))


def squared_distance(axes: torch.Tensor, i: torch.Tensor, j: torch.Tensor) -> torch.Tensor:
    """|p_i - p_j|^2 from [D, N] coordinates, summed axis by axis as NumPy sums a row (same rounding)."""
    total = None
    for axis in axes:
        gap = axis.index_select(0, i).sub_(axis.index_select(0, j))
        gap.mul_(gap)
        total = gap if total is None else total.add_(gap)
    return total


def cell_coordinates(pos: torch.Tensor, radius: float, split: int = 1) -> torch.Tensor:
    """[N, D] int64 cell coordinates (cells of side >= R / split), >= split, each axis compressed: gaps
    of up to ``split`` cells stay, larger ones become split + 1, so far-apart particles cannot overflow."""
    exact = torch.float32 if pos.device.type == "mps" else torch.float64    # MPS has no float64
    x = pos.to(exact)
    low = x.amin(dim=0)
    span = float((x.amax(dim=0) - low).max())
    # cells a little wider than R: no rounding of the binning or the distance hides a pair
    margin = 8 * torch.finfo(pos.dtype).eps + 8 * torch.finfo(exact).eps * (span / radius + 1)
    bins = torch.floor((x - low) * (split / (radius * (1 + margin))))
    coords = torch.empty(bins.shape, dtype=torch.int64, device=pos.device)
    for axis in range(bins.shape[1]):
        values, inverse = torch.unique(bins[:, axis], return_inverse=True)
        steps = values.diff().clamp_(max=split + 1).long()
        coords[:, axis] = torch.cat([steps.new_zeros(1), steps.cumsum(0)])[inverse] + split
    return coords


def cell_strides(cells: torch.Tensor, split: int = 1) -> torch.Tensor:
    """Strides [D] of a row-major cell key with ``split`` free cells on every side (no offset wraps)."""
    extent = [int(e) + split + 1 for e in cells.amax(dim=0).tolist()]
    if math.prod(extent) >= 2**62:
        raise ValueError(f"radius_graph: {extent} cells per axis overflow an int64 key; use method='kdtree'")
    strides = [math.prod(extent[axis + 1:]) for axis in range(len(extent))]
    return torch.tensor(strides, dtype=torch.int64, device=cells.device)


def strip_offsets(dim: int, split: int = 1) -> list[tuple[int, ...]]:
    """Offsets of the strips of 2 split + 1 cells along the last axis that see every pair of cells
    within reach once: the own strip (forward only) and the lexicographically positive ones over the
    other axes."""
    reach = range(-split, split + 1)
    return [(*o, 0) for o in itertools.product(reach, repeat=dim - 1) if o >= (0,) * (dim - 1)]


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


# ---- the model's graph of a sample ----------------------------------------------------------------


@dataclass
class Graph:
    """Model inputs of one or several disjoint samples stacked along the particle axis."""

    window: torch.Tensor        # [K, N, D] positions (m)
    types: torch.Tensor         # [N] long
    kinematic: torch.Tensor     # [N] bool
    edge_index: torch.Tensor    # [2, E]
    props: torch.Tensor | None  # [N, F] normalised properties, None for a scene without any
    capped_receivers: int = 0   # receivers that had more senders than the neighbour cap (0 without a cap)
    dropped_edges: int = 0      # edges the neighbour cap dropped


def neighbour_edges(position: torch.Tensor, radius: float, kinematic: torch.Tensor | np.ndarray | None,
                    max_neighbours: int | None = None) -> CappedEdges:
    """The radius graph of one frame ``position`` [N, D] on its device (no edge between two ``kinematic``
    particles when given), cut to ``max_neighbours`` senders per receiver when set (null: the radius
    graph as it is, nothing counted)."""
    edges = radius_graph(position, radius, kinematic).to(position.device)
    if max_neighbours is None:
        return CappedEdges(edges, 0, 0)
    return cap_neighbours(edges, position, max_neighbours)


def build_graph(window: torch.Tensor, types: torch.Tensor, kinematic: torch.Tensor, radius: float,
                props: torch.Tensor | None = None, skip_kinematic_pairs: bool = True,
                max_neighbours: int | None = None) -> Graph:
    """One sample's graph on its last frame (edges rebuilt every step, article 4.2.2); no edge
    between two kinematic particles unless ``skip_kinematic_pairs`` is off (a runtime switch); each
    receiver's ``max_neighbours`` nearest senders where that cap is set. The edges live on the window's
    device, wherever the neighbour search ran."""
    edges = neighbour_edges(window[-1], radius, kinematic if skip_kinematic_pairs else None, max_neighbours)
    return Graph(window, types, kinematic, edges.edge_index, props, edges.capped_receivers, edges.dropped_edges)


def prune_isolated(graph: Graph) -> tuple[Graph, torch.Tensor]:
    """The graph without the unpredicted particles (``graph.kinematic``) whose only edge is their self edge.

    Such a particle neither sends to nor receives from any other node, so it cannot change any
    prediction: leaving it out is exact, and it saves the node MLPs of every updater (in the
    Solid-GN scenes two thirds of the nodes are wall particles far from the soil). Returns the
    reduced graph and the indices of the kept particles in the full one.
    """
    edges = graph.edge_index
    keep = ~graph.kinematic
    linked = edges[:, edges[0] != edges[1]]
    keep[linked[0]] = True
    keep[linked[1]] = True
    index = keep.nonzero().squeeze(1)
    remap = torch.full((keep.numel(),), -1, dtype=torch.long, device=edges.device)
    remap[index] = torch.arange(index.numel(), device=edges.device)
    sub_edges = remap[edges]
    sub_edges = sub_edges[:, (sub_edges >= 0).all(dim=0)]
    props = None if graph.props is None else graph.props[index]
    return Graph(graph.window[:, index], graph.types[index], graph.kinematic[index], sub_edges, props,
                 graph.capped_receivers, graph.dropped_edges), index


def stack_graphs(graphs: list[Graph]) -> Graph:
    """Disjoint union of several samples (a mini-batch), edge indices offset per sample."""
    if len(graphs) == 1:
        return graphs[0]
    offsets = np.cumsum([0] + [g.types.numel() for g in graphs[:-1]])
    props = [g.props for g in graphs]
    return Graph(
        window=torch.cat([g.window for g in graphs], dim=1),
        types=torch.cat([g.types for g in graphs]),
        kinematic=torch.cat([g.kinematic for g in graphs]),
        edge_index=torch.cat([g.edge_index + int(o) for g, o in zip(graphs, offsets, strict=True)], dim=1),
        props=None if props[0] is None else torch.cat(props),
        capped_receivers=sum(g.capped_receivers for g in graphs),
        dropped_edges=sum(g.dropped_edges for g in graphs),
    )
