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

With a neighbour cap N (the model's ``max_neighbours``: each receiver keeps its N nearest senders within
R, :func:`surrogate.graph.cap_neighbours`) a contact is also missed when the sender is not among the
receiver's N nearest at t. A cap acts per receiver, so the capped rate counts *directed* contacts: a
moving receiver i and a sender j that touches it at t+1 (a pair of two moving particles counts twice,
a pair with a kinematic one once; kinematic receivers are never predicted). :func:`contact_ranks` gives
every directed contact its centre distance at t and the sender's rank among the receiver's
neighbours at t (how many particles are nearer to i than j), so that one pass over the data answers
every (R, N): missed when distance >= R or rank >= N (:func:`capped_misses`). ``graphdem contacts``
prints that table for a dataset, beside the senders per receiver each (R, N) costs.
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


RANK_LIMIT = 64          # contact_ranks counts ranks up to this; a cap above it cannot be scored


def contact_ranks(position: np.ndarray, radius: np.ndarray, kinematic: np.ndarray,
                  limit: int = RANK_LIMIT) -> tuple[np.ndarray, np.ndarray]:
    """Every directed next-frame contact (module docstring) over the frame pairs (t, t+1) of ``position``
    [T, N, D], in frame order: its centre distance at t and the sender's rank at t among the receiver's
    neighbours (0: the nearest other particle), ``limit`` standing for ``limit`` or more. Particles at
    exactly the same distance are ranked in the k-d tree's order (the cap breaks such ties by index)."""
    position = np.asarray(position, np.float64)
    moving = ~np.asarray(kinematic, bool)
    n = position.shape[1]
    distances, ranks = [np.empty(0)], [np.empty(0, dtype=np.int64)]
    for t in range(position.shape[0] - 1):
        pairs = contact_pairs(position[t + 1], radius, moving)
        a, b = pairs[:, 0], pairs[:, 1]
        receiver = np.concatenate([a[moving[a]], b[moving[b]]])
        sender = np.concatenate([b[moving[a]], a[moving[b]]])
        if receiver.size == 0:
            continue
        x = position[t]
        k = min(limit + 1, n)                          # the receiver itself and its `limit` nearest others
        _, nearest = cKDTree(x).query(x[receiver], k=k)
        nearest = np.asarray(nearest).reshape(receiver.size, k)
        hit = nearest == sender[:, None]
        column = hit.argmax(axis=1)
        itself_before = ((nearest == receiver[:, None]) & (np.arange(k)[None, :] < column[:, None])).sum(axis=1)
        ranks.append(np.where(hit.any(axis=1), column - itself_before, limit).astype(np.int64))
        distances.append(np.linalg.norm(x[receiver] - x[sender], axis=1))
    return np.concatenate(distances), np.concatenate(ranks)


def scorable_cap(cap: int | None, limit: int = RANK_LIMIT) -> int | None:
    """``cap`` itself where the ranks of :func:`contact_ranks` can score it (None, or 1 .. ``limit``)."""
    if cap is not None and not 1 <= cap <= limit:
        raise ValueError(f"a neighbour cap of {cap!r} cannot be scored: ranks are counted up to {limit}")
    return cap


def capped_misses(distances: np.ndarray, ranks: np.ndarray, connectivity_radius: float, cap: int | None,
                  limit: int = RANK_LIMIT) -> int:
    """How many directed contacts (:func:`contact_ranks`) a graph of radius ``connectivity_radius`` capped at
    ``cap`` senders per receiver (None: no cap) misses: distance >= R, or rank >= cap."""
    cap = scorable_cap(cap, limit)
    missed = ~(np.asarray(distances) < connectivity_radius)
    if cap is not None:
        missed |= np.asarray(ranks) >= cap
    return int(missed.sum())


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


def cap_table(sims, radii: list[float], caps: list[int | None]) -> list[dict]:
    """For each connectivity radius in ``radii`` and cap in ``caps`` (None: no cap), over ``sims`` (an iterable
    of (position [T, N, D], radius [N], kinematic [N])): the directed next-frame contacts, those missed, their
    share, and the senders per moving receiver the capped graph keeps in the frames a graph is built on (all
    but the last; its self edge not counted; the graph's cost grows with it). Rows in the order radius, then cap."""
    from surrogate.neighbours import neighbour_counts
    caps = [scorable_cap(cap) for cap in caps]              # before the pass over the data
    distances, ranks = [], []
    senders = {(r, c): 0 for r in radii for c in caps}
    receivers = 0
    for position, radius, kinematic in sims:
        d, k = contact_ranks(position, radius, kinematic)
        distances.append(d)
        ranks.append(k)
        moving = ~np.asarray(kinematic, bool)
        built_on = np.asarray(position)[:-1]           # the frames a graph is built on: all but the last
        receivers += int(moving.sum()) * len(built_on)
        for r in radii:
            counts = np.stack([neighbour_counts(frame, r, kinematic)[moving] for frame in built_on])
            for c in caps:
                senders[r, c] += int((counts if c is None else np.minimum(counts, c)).sum())
    distances = np.concatenate(distances) if distances else np.empty(0)
    ranks = np.concatenate(ranks) if ranks else np.empty(0, dtype=np.int64)
    rows = []
    for r in radii:
        for c in caps:
            missed = capped_misses(distances, ranks, r, c)
            rows.append({"connectivity_radius": r, "cap": c, "contacts": len(distances), "missed": missed,
                         "miss_rate": missed / len(distances) if len(distances) else float("nan"),
                         "senders_per_receiver": senders[r, c] / receivers if receivers else float("nan")})
    return rows
