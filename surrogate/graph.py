"""Neighbour graphs for Graph-DEM (article 4.2.2), built with a k-d tree.

PyG's ``radius_graph`` needs pyg-lib; we build the same graph with scipy's cKDTree: a directed
edge (sender i -> receiver j) for every pair closer than R, in both directions, plus a self
edge on every node. Pairs of two kinematic particles get no edge (their interaction never
changes a prediction).
"""

from __future__ import annotations

import numpy as np
import torch
from scipy.spatial import cKDTree


def radius_graph(pos: torch.Tensor | np.ndarray, radius: float, kinematic: np.ndarray | None = None,
                 self_loops: bool = True) -> torch.Tensor:
    """``edge_index`` [2, E] (row 0 senders, row 1 receivers) of all pairs with distance < radius."""
    x = pos.detach().cpu().numpy() if isinstance(pos, torch.Tensor) else np.asarray(pos)
    n = len(x)
    pairs = cKDTree(x).query_pairs(radius, output_type="ndarray") if n > 1 else np.empty((0, 2), int)
    if len(pairs):
        dist = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
        pairs = pairs[dist < radius]                   # strict, as the article writes it
        if kinematic is not None:
            kin = np.asarray(kinematic, bool)
            pairs = pairs[~(kin[pairs[:, 0]] & kin[pairs[:, 1]])]
    senders = np.concatenate([pairs[:, 0], pairs[:, 1]])
    receivers = np.concatenate([pairs[:, 1], pairs[:, 0]])
    if self_loops:
        senders = np.concatenate([senders, np.arange(n)])
        receivers = np.concatenate([receivers, np.arange(n)])
    return torch.from_numpy(np.stack([senders, receivers]).astype(np.int64))
