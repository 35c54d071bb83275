"""The contact-miss rate of a connectivity radius, by hand and against brute force."""

import itertools
import math

import numpy as np
import pytest

from surrogate import contacts

# Three discs of radius 1 in 2D: A and B move, C is kinematic. From frame 0 to 1, B comes from 5 m to
# 1.5 m of A (a contact) and C from 3 m to 1.8 m of A (a contact); B and C stay 2.34 m apart (none).
THREE = np.array([[[0.0, 0.0], [5.0, 0.0], [0.0, 3.0]],
                  [[0.0, 0.0], [1.5, 0.0], [0.0, 1.8]]])
RADII = np.ones(3)
C_KINEMATIC = np.array([False, False, True])


def test_three_discs_by_hand():
    assert contacts.contact_misses(THREE, RADII, 4.0, C_KINEMATIC) == (1, 2)       # A-B was 5 m apart: missed
    assert contacts.contact_miss_rate(THREE, RADII, 4.0, C_KINEMATIC) == 0.5
    assert contacts.contact_miss_rate(THREE, RADII, 6.0, C_KINEMATIC) == 0.0       # both pairs within 6 m
    assert contacts.contact_miss_rate(THREE, RADII, 3.0, C_KINEMATIC) == 1.0       # 3 m is not closer than 3 m
    # A kinematic as well: the A-C contact joins two kinematic particles and does not count
    assert contacts.contact_misses(THREE, RADII, 4.0, np.array([True, False, True])) == (1, 1)
    # larger discs: B-C touch at frame 1 (2.34 m < 1.2 + 1.2), 5.83 m apart at frame 0
    assert contacts.contact_misses(THREE, np.full(3, 1.2), 4.0, C_KINEMATIC) == (2, 3)
    assert math.isnan(contacts.contact_miss_rate(THREE[:1], RADII, 4.0, C_KINEMATIC))   # one frame: no contact


def test_edges_per_particle_by_hand():
    # R = 4: frame 0 has the pair A-C, frame 1 all three pairs; both directions plus 3 self edges
    assert contacts.edges_per_particle(THREE, 4.0, C_KINEMATIC) == pytest.approx((5 + 9) / 2 / 3)
    # A and C kinematic: their pair has no edge
    assert contacts.edges_per_particle(THREE, 4.0, np.array([True, False, True])) == pytest.approx((3 + 7) / 2 / 3)


def brute_force(position, radius, r_graph, kinematic):
    missed = total = 0
    for t in range(len(position) - 1):
        for i, j in itertools.combinations(range(position.shape[1]), 2):
            if kinematic[i] and kinematic[j]:
                continue
            if np.linalg.norm(position[t + 1, i] - position[t + 1, j]) < radius[i] + radius[j]:
                total += 1
                missed += np.linalg.norm(position[t, i] - position[t, j]) >= r_graph
    return missed, total


@pytest.mark.parametrize("dim", [2, 3])
def test_random_packings_against_brute_force(dim):
    rng = np.random.default_rng(dim)
    n, frames = 60, 6
    start = rng.uniform(0, 6, size=(n, dim))
    velocity = rng.normal(0, 0.4, size=(n, dim))
    position = start + velocity * np.arange(frames)[:, None, None]
    radius = rng.uniform(0.3, 0.6, size=n)
    kinematic = rng.random(n) < 0.3
    rates = []
    for r_graph in (0.5, 1.0, 1.5, 3.0):
        missed, total = contacts.contact_misses(position, radius, r_graph, kinematic)
        assert (missed, total) == brute_force(position, radius, r_graph, kinematic)
        rates.append(missed / total)
    assert total > 20 and rates[0] > 0.5 and rates[-1] < rates[0]
    assert rates == sorted(rates, reverse=True)                     # a larger R misses fewer contacts
    edges = [contacts.edges_per_particle(position, r, kinematic) for r in (1.0, 2.0)]
    for r, value in zip((1.0, 2.0), edges, strict=True):
        expected = np.mean([(n + 2 * sum(1 for i, j in itertools.combinations(range(n), 2)
                                         if not (kinematic[i] and kinematic[j])
                                         and np.linalg.norm(frame[i] - frame[j]) < r)) / n for frame in position])
        assert value == pytest.approx(expected)


def test_the_miss_floor_is_the_radius_that_misses_at_most_the_share():
    """miss_floor(q): every R above it misses at most q of the contacts, R equal to it misses more (by hand on the
    three discs, then on random motion against the brute-force rate)."""
    distances = contacts.contact_distances(THREE, RADII, C_KINEMATIC)
    assert sorted(distances.tolist()) == pytest.approx([3.0, 5.0])          # A-C 3 m apart before, A-B 5 m
    assert contacts.miss_floor(distances, 0.0) == 5.0                         # miss none: R > 5 m
    assert contacts.miss_floor(distances, 0.5) == 3.0                         # miss one of two: R > 3 m
    rng = np.random.default_rng(7)
    walk = np.cumsum(rng.normal(0.0, 0.4, (12, 40, 2)), axis=0) + rng.uniform(0, 12, (1, 40, 2))
    radii, kinematic = rng.uniform(0.4, 0.8, 40), rng.random(40) < 0.2
    distances = contacts.contact_distances(walk, radii, kinematic)
    assert len(distances) > 50
    for rate in (0.0, 0.01, 0.1, 0.5):
        r = contacts.miss_floor(distances, rate)
        assert contacts.contact_miss_rate(walk, radii, np.nextafter(r, np.inf), kinematic) <= rate
        assert contacts.contact_miss_rate(walk, radii, r, kinematic) > rate
    assert math.isnan(contacts.miss_floor(np.empty(0), 0.01))
    with pytest.raises(ValueError, match=r"contact-miss rate is in \[0, 1\); got 1.0"):
        contacts.miss_floor(distances, 1.0)


def graph_misses(position, radius, kinematic, r_graph, cap):
    """Directed next-frame contacts (moving receiver) whose sender -> receiver edge the model's own capped
    graph at t lacks: radius_graph, then cap_neighbours, as the simulator builds it."""
    import torch

    from surrogate.graph import cap_neighbours, radius_graph
    missed = total = 0
    for t in range(len(position) - 1):
        x = torch.from_numpy(position[t])
        edges = radius_graph(x, r_graph, torch.from_numpy(kinematic))
        if cap is not None:
            edges = cap_neighbours(edges, x, cap).edge_index
        present = set(zip(edges[0].tolist(), edges[1].tolist(), strict=True))
        for i, j in itertools.permutations(range(position.shape[1]), 2):
            if kinematic[i] or np.linalg.norm(position[t + 1, i] - position[t + 1, j]) >= radius[i] + radius[j]:
                continue
            total += 1
            missed += (j, i) not in present                        # sender j, receiver i
    return missed, total


@pytest.mark.parametrize("dim", [2, 3])
def test_capped_misses_are_the_contacts_the_capped_graph_lacks(dim):
    rng = np.random.default_rng(10 + dim)
    n, frames = 50, 5
    position = np.cumsum(rng.normal(0.0, 0.35, (frames, n, dim)), axis=0) + rng.uniform(0, 4.5, (1, n, dim))
    radius = rng.uniform(0.3, 0.6, size=n)
    kinematic = rng.random(n) < 0.25
    distances, ranks = contacts.contact_ranks(position, radius, kinematic)
    rates = {}
    for r_graph in (1.0, 1.6, 3.0):
        for cap in (None, 1, 2, 4, 8):
            missed = contacts.capped_misses(distances, ranks, r_graph, cap)
            assert (missed, len(distances)) == graph_misses(position, radius, kinematic, r_graph, cap)
            rates[r_graph, cap] = missed / len(distances)
    assert len(distances) > 40
    assert rates[3.0, 1] > rates[3.0, 4] > rates[3.0, None]          # a tighter cap misses more
    assert rates[1.0, None] > rates[3.0, None]
    with pytest.raises(ValueError, match="cap of 65 cannot be scored"):
        contacts.capped_misses(distances, ranks, 3.0, 65)


def test_the_cap_table_counts_senders_per_receiver_by_hand():
    """Three discs in a row 1 m apart (radius 0.6, the middle one kinematic), then the ends pressed in by 0.1 m,
    then by 0.2 m: at the second frame two directed contacts (each end <- the middle; the middle is a kinematic
    receiver, the ends 1.8 m apart do not touch), 1 m apart before; at the third frame the same two, 0.9 m
    apart before. Senders per moving receiver over the frames a graph is built on (the first two): the middle
    at R = 1.5 m (1); at R = 1.9 m also the other end in the second frame only (2.0 then 1.8 m away: 1.5); at
    R = 2.5 m in both (2); capped at one sender, 1 everywhere."""
    position = np.array([[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], [[0.1, 0.0], [1.0, 0.0], [1.9, 0.0]],
                         [[0.2, 0.0], [1.0, 0.0], [1.8, 0.0]]])
    kinematic = np.array([False, True, False])
    rows = contacts.cap_table([(position, np.full(3, 0.6), kinematic)], [1.5, 1.9, 2.5], [None, 1])
    table = {(row["connectivity_radius"], row["cap"]): row for row in rows}
    assert all(row["contacts"] == 4 and row["missed"] == 0 for row in rows)
    assert [table[r, None]["senders_per_receiver"] for r in (1.5, 1.9, 2.5)] == [1.0, 1.5, 2.0]
    assert [table[r, 1]["senders_per_receiver"] for r in (1.5, 1.9, 2.5)] == [1.0, 1.0, 1.0]
    assert contacts.cap_table([(position, np.full(3, 0.6), kinematic)], [0.95], [None])[0]["missed"] == 2
    with pytest.raises(ValueError, match="cap of 0 cannot be scored"):
        contacts.cap_table([], [1.0], [0])
