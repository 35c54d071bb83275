"""How small the connectivity radius R may be: the contacts a graph of radius R would miss.

The network predicts frame t+1 from a graph built on frame t (article 4.2.2). Two particles that
touch at t+1 but are R or farther apart at t have no edge in that graph: the model cannot see the
contact it has to predict. Over a trajectory,

    contact-miss rate(R) = #{(t, i, j): |p_i - p_j| < r_i + r_j at t+1, |p_i - p_j| >= R at t}
                           / #{(t, i, j): |p_i - p_j| < r_i + r_j at t+1}

counting the pairs with at least one moving particle (the graph never joins two kinematic ones,
and their contact changes no prediction), every frame pair (t, t+1) of the trajectory. A radius
with a miss rate of 0 on the data loses no contact in one step; the graph's cost grows with the
edges per particle, about as R to the power of the dimension.

The miss rate gives R a floor, not a value: :func:`miss_floor` is the radius R must exceed to miss at most
a given share. On this project's scenes that floor is 1.1-1.5 mean diameters (docs/surrogate.md,
"Connectivity radius"), while R also sets how far one message reaches, which is chosen on valid.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def contact_pairs(position: np.ndarray, radius: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """[P, 2] index pairs (i < j) of one frame ``position`` [N, D] whose centres are closer than
    r_i + r_j, with at least one of the two in ``moving``."""
    x = np.asarray(position, np.float64)
    r = np.asarray(radius, np.float64)
    if len(x) < 2:
        return np.empty((0, 2), dtype=np.int64)
    pairs = cKDTree(x).query_pairs(2 * float(r.max()), output_type="ndarray")
    distance = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
    touching = (distance < r[pairs[:, 0]] + r[pairs[:, 1]]) & (moving[pairs[:, 0]] | moving[pairs[:, 1]])
    return pairs[touching].astype(np.int64)


def contact_distances(position: np.ndarray, radius: np.ndarray, kinematic: np.ndarray) -> np.ndarray:
    """The centre distance at t of every contact at t+1 (module docstring), over every frame pair (t, t+1) of
    ``position`` [T, N, D], in frame order: a graph of radius R misses exactly those at R or farther."""
    position = np.asarray(position, np.float64)
    moving = ~np.asarray(kinematic, bool)
    out = [np.empty(0)]
    for t in range(position.shape[0] - 1):
        pairs = contact_pairs(position[t + 1], radius, moving)
        out.append(np.linalg.norm(position[t, pairs[:, 0]] - position[t, pairs[:, 1]], axis=1))
    return np.concatenate(out)


def contact_misses(position: np.ndarray, radius: np.ndarray, connectivity_radius: float,
                   kinematic: np.ndarray) -> tuple[int, int]:
    """(missed, contacts) over every frame pair of ``position`` [T, N, D]: the contacts at t+1 (module
    docstring) and those of them whose centres are ``connectivity_radius`` or farther apart at t."""
    distances = contact_distances(position, radius, kinematic)
    return missed_at(distances, connectivity_radius), len(distances)


def missed_at(distances: np.ndarray, connectivity_radius: float) -> int:
    """How many of the contacts whose earlier centre distances are ``distances`` (:func:`contact_distances`) a
    graph of radius ``connectivity_radius`` misses: those at R or farther (a NaN distance counts as missed)."""
    return int((~(np.asarray(distances) < connectivity_radius)).sum())


def miss_floor(distances: np.ndarray, miss_rate: float) -> float:
    """The radius R must exceed to miss at most ``miss_rate`` of the contacts whose earlier centre distances are
    ``distances`` (:func:`contact_distances`): with m = floor(miss_rate x n) misses allowed, the (m+1)-th largest
    distance (every R above it misses at most m, R equal to it misses m+1). NaN without contacts."""
    if not 0.0 <= miss_rate < 1.0:
        raise ValueError(f"a contact-miss rate is in [0, 1); got {miss_rate!r}")
    distances = np.asarray(distances, np.float64)
    if distances.size == 0:
        return float("nan")
    allowed = int(np.floor(miss_rate * distances.size))
    return float(np.sort(distances)[::-1][allowed])


def contact_miss_rate(position: np.ndarray, radius: np.ndarray, connectivity_radius: float,
                      kinematic: np.ndarray) -> float:
    """The contact-miss rate of ``position`` [T, N, D] at R = ``connectivity_radius`` (module docstring);
    NaN when no two particles touch in any frame after the first."""
    missed, contacts = contact_misses(position, radius, connectivity_radius, kinematic)
    return missed / contacts if contacts else float("nan")


def edges_per_particle(position: np.ndarray, connectivity_radius: float, kinematic: np.ndarray) -> float:
    """Mean over the frames of ``position`` [T, N, D] of the edges of the rollout's radius graph at
    R = ``connectivity_radius`` (both directions and the self edges, no edge between two kinematic
    particles; before any pruning) per particle."""
    import torch  # here, so that the dataset stage's contact count needs no torch

    from surrogate.graph import radius_graph
    position = np.asarray(position)
    kin = torch.from_numpy(np.asarray(kinematic, bool))
    edges = [radius_graph(torch.from_numpy(np.ascontiguousarray(frame)), connectivity_radius, kin).shape[1]
             for frame in position]
    return float(np.mean(edges)) / position.shape[1]
