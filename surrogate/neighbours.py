"""Neighbour counts of the radius graph, and what a per-particle cap on them would cut; NumPy only.

The graph (:mod:`surrogate.graph`) joins every pair closer than R, both ways, with no pair of two
kinematic particles. A receiver's neighbour count is the number of senders it has other than itself
(its self edge is never counted, and a cap never drops it). The model config's ``max_neighbours`` = N
keeps each receiver's N nearest senders (:func:`surrogate.graph.cap_neighbours`); a receiver with more
than N is *capped*, and its senders beyond the N nearest are *dropped edges*.

:func:`close_pairs` is the graph's k-d tree search itself (``surrogate.graph.kdtree_pairs`` calls it), so
the counts here are the graph's, without torch: the dataset stage counts the train split's neighbours
with it (``stats.json``, ``neighbour_counts``), so that a cap can be chosen from data.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

PERCENTILE = 99          # the neighbour count reported beside the largest: 99 % of receivers have at most it


def close_pairs(x: np.ndarray, radius: float) -> np.ndarray:
    """[P, 2] index pairs (i < j) of the rows of ``x`` [N, D] closer than ``radius``: the squared distance,
    summed axis by axis in x's dtype, below R^2 rounded to that dtype (the graph's rule, surrogate/graph.py)."""
    if len(x) < 2:
        return np.empty((0, 2), dtype=np.int64)
    # the tree measures in float64: a little beyond R, so that the strict test below decides
    pairs = cKDTree(x).query_pairs(radius * (1 + 1e-6), output_type="ndarray")
    squared = ((x[pairs[:, 0]] - x[pairs[:, 1]]) ** 2).sum(axis=1)
    return pairs[squared < np.asarray(radius * radius, dtype=x.dtype)]


def neighbour_counts(position: np.ndarray, radius: float, kinematic: np.ndarray | None = None) -> np.ndarray:
    """[N] int64: each particle's senders within ``radius`` in one frame ``position`` [N, D], itself not
    counted; no pair of two ``kinematic`` particles when given (the graph's rule)."""
    x = np.asarray(position)
    pairs = close_pairs(x, radius)
    if kinematic is not None:
        kin = np.asarray(kinematic, bool)
        pairs = pairs[~(kin[pairs[:, 0]] & kin[pairs[:, 1]])]
    return np.bincount(pairs.ravel(), minlength=len(x)).astype(np.int64)


def check_cap(max_neighbours: int | None, name: str = "model.max_neighbours") -> int | None:
    """``max_neighbours`` itself where it is null or an integer >= 1; a ValueError naming ``name`` otherwise."""
    if max_neighbours is None:
        return None
    if isinstance(max_neighbours, bool) or not isinstance(max_neighbours, int | np.integer) or max_neighbours < 1:
        raise ValueError(f"{name} = {max_neighbours!r}: null (no cap) or an integer >= 1 (senders kept per "
                         f"receiver, its self edge not counted)")
    return int(max_neighbours)


@dataclass
class Histogram:
    """Receivers per neighbour count: ``receivers[c]`` receivers had c senders (itself not counted)."""

    receivers: np.ndarray = field(default_factory=lambda: np.zeros(1, dtype=np.int64))

    @classmethod
    def of(cls, counts: np.ndarray) -> Histogram:
        """The histogram of per-receiver counts (e.g. one frame's :func:`neighbour_counts`)."""
        out = cls()
        out.add(counts)
        return out

    @classmethod
    def from_list(cls, receivers: list[int]) -> Histogram:
        """The histogram stored in ``stats.json`` (``neighbour_counts.histogram``)."""
        return cls(np.asarray(receivers, dtype=np.int64).reshape(-1))

    def add(self, counts: np.ndarray) -> None:
        """Add the receivers of per-receiver neighbour ``counts``."""
        self.merge(Histogram(np.bincount(np.asarray(counts, dtype=np.int64).reshape(-1))))

    def merge(self, other: Histogram) -> None:
        """Add another histogram's receivers."""
        size = max(len(self.receivers), len(other.receivers))
        self.receivers = (np.pad(self.receivers, (0, size - len(self.receivers)))
                          + np.pad(other.receivers, (0, size - len(other.receivers))))

    @property
    def total(self) -> int:
        return int(self.receivers.sum())

    @property
    def largest(self) -> int:
        """The largest neighbour count (0 without receivers)."""
        seen = np.flatnonzero(self.receivers)
        return int(seen[-1]) if len(seen) else 0

    def percentile(self, q: float) -> int:
        """The smallest count that at least q % of the receivers do not exceed (0 without receivers)."""
        if self.total == 0:
            return 0
        return int(np.searchsorted(np.cumsum(self.receivers), q / 100 * self.total - 1e-9 * self.total))

    def mean(self) -> float:
        return float(np.dot(np.arange(len(self.receivers)), self.receivers) / self.total) if self.total else 0.0

    def capped_fraction(self, cap: int) -> float:
        """The share of receivers with more than ``cap`` senders: those a cap of ``cap`` truncates."""
        return float(self.receivers[cap + 1:].sum() / self.total) if self.total else 0.0

    def dropped_fraction(self, cap: int) -> float:
        """The share of the edges between two particles (self edges not counted) a cap of ``cap`` drops."""
        counts = np.arange(len(self.receivers))
        edges = float(np.dot(counts, self.receivers))
        dropped = float(np.dot(np.maximum(counts - cap, 0), self.receivers))
        return dropped / edges if edges else 0.0

    def summary(self, max_neighbours: int | None = None) -> dict:
        """The ``neighbour_counts`` entry of ``stats.json``: receivers counted, the largest count, the
        ``PERCENTILE``-th percentile, the mean, the histogram, and for a cap the shares it truncates
        (receivers) and drops (edges); null without a cap."""
        cap = check_cap(max_neighbours, "max_neighbours")
        return {"receivers": self.total, "max": self.largest, f"p{PERCENTILE}": self.percentile(PERCENTILE),
                "mean": self.mean(), "histogram": [int(r) for r in self.receivers[:self.largest + 1]],
                "max_neighbours": cap,
                "capped_receiver_fraction": None if cap is None else self.capped_fraction(cap),
                "dropped_edge_fraction": None if cap is None else self.dropped_fraction(cap)}
