"""Plausibility of a trajectory, scored alike for the DEM truth and every prediction (docs/surrogate.md,
"Plausibility"): how deep particles overlap, how many leave the box or pass a wall, and how much kinetic energy
moves.

Per frame:

- ``Max overlap``: the largest overlap r_i + r_j - |x_i - x_j| over pairs, divided by the pair's smaller
  radius (pairs of two kinematic particles are geometry and left out);
- ``P99 overlap``: the 99th percentile of the same ratio over the overlapping pairs;
- ``Outside box``: moving particles outside the dataset's box (through a wall or out of the domain);
- ``Through wall``: moving particles whose step from the frame before passed a kinematic particle (a wall,
  floor, box or platen disc): their straight path relative to it came within the contact distance r_i + r_k
  and ended past it, the path test of :func:`surrogate.correction.kinematic_passages` with no allowed overlap
  (pairs are searched within 2 max(r) plus the frame's largest steps, at most ``PATH_REACH`` max(r)); the box's
  own walls are ``Outside box``'s. NaN at frame 0 (no step);
- ``Kinetic energy``: 1/2 sum_i m_i |x_i(t) - x_i(t-1)|^2 / dt^2 over the moving particles, from frame
  differences as for the data (J, or J per metre of depth in 2D).

Over a test set, the overlaps and the kinetic energy are summarised by their largest value
(:data:`AGGREGATE`), the particles outside by their sum (particle-frames), the passages through a wall by their
sum (particle-steps).
"""

from __future__ import annotations

import numpy as np
import torch

from generators.blowup import overlap_fractions
from surrogate.correction import kinematic_passages

OVERLAP_QUANTILE = 99
NAMES = ("Max overlap", f"P{OVERLAP_QUANTILE} overlap", "Outside box", "Through wall", "Kinetic energy")
UNITS = {"Max overlap": "radii", f"P{OVERLAP_QUANTILE} overlap": "radii", "Outside box": "particles",
         "Through wall": "particles", "Kinetic energy": "J"}
AGGREGATE = {"Max overlap": "max", f"P{OVERLAP_QUANTILE} overlap": "max", "Outside box": "sum",
             "Through wall": "sum", "Kinetic energy": "max"}


def kinetic_energy(position: np.ndarray, mass: np.ndarray, moving: np.ndarray, frame_interval: float) -> np.ndarray:
    """[T] kinetic energy of the moving particles, 1/2 sum m |x_t - x_(t-1)|^2 / dt^2 (J, or J per m in
    2D); frame 0 has no velocity (NaN)."""
    x = np.asarray(position, np.float64)[:, moving]
    v2 = (np.diff(x, axis=0) ** 2).sum(axis=-1) / frame_interval**2
    return np.concatenate([[np.nan], 0.5 * (v2 * np.asarray(mass, float)[moving]).sum(axis=-1)])


def through_wall(previous: np.ndarray, position: np.ndarray, radius: np.ndarray, kinematic: np.ndarray) -> int:
    """The number of moving particles whose step from ``previous`` [N, D] to ``position`` [N, D] passed a
    kinematic particle (module docstring)."""
    moving = torch.from_numpy(~np.asarray(kinematic, bool))
    passed = kinematic_passages(torch.from_numpy(np.asarray(previous, np.float64)),
                                torch.from_numpy(np.asarray(position, np.float64)),
                                torch.from_numpy(np.asarray(radius, np.float64)), moving, 0.0)
    return int(torch.unique(passed.particle).numel())


def per_frame(position: np.ndarray, radius: np.ndarray, mass: np.ndarray, kinematic: np.ndarray,
              lower: np.ndarray, upper: np.ndarray, frame_interval: float) -> dict[str, np.ndarray]:
    """[T] values of every plausibility measure (module docstring) of the trajectory ``position`` [T, N, D];
    NaN at frames with a non-finite position."""
    position = np.asarray(position, np.float64)
    kinematic = np.asarray(kinematic, bool)
    moving = ~kinematic
    radius = np.asarray(radius, np.float64)
    n = position.shape[0]
    out = {name: np.full(n, np.nan) for name in NAMES}
    out["Kinetic energy"] = kinetic_energy(position, mass, moving, frame_interval)
    for t in range(n):
        x = position[t]
        if not np.isfinite(x).all():
            out["Kinetic energy"][t] = np.nan
            continue
        overlaps = overlap_fractions(x, radius, kinematic)
        out["Max overlap"][t] = float(overlaps.max()) if len(overlaps) else 0.0
        out[f"P{OVERLAP_QUANTILE} overlap"][t] = float(np.percentile(overlaps, OVERLAP_QUANTILE)) \
            if len(overlaps) else 0.0
        out["Outside box"][t] = float(((x[moving] < lower) | (x[moving] > upper)).any(axis=-1).sum())
        if t > 0 and np.isfinite(position[t - 1]).all():
            out["Through wall"][t] = float(through_wall(position[t - 1], x, radius, kinematic))
    return out


def of_trajectory(position: np.ndarray, traj) -> dict[str, np.ndarray]:
    """:func:`per_frame` with the particles, box and frame interval of the H5MD trajectory ``traj``."""
    return per_frame(position, traj.radius, traj.mass, traj.kinematic, np.asarray(traj.box_lower, np.float64),
                     np.asarray(traj.box_upper, np.float64), float(np.median(np.diff(np.asarray(traj.time, float)))))
