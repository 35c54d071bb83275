"""Blow-up detection for DEM runs of every engine: non-finite values, escapes, excessive overlaps, and
mechanical energy that grows although nothing supplies it."""

from __future__ import annotations

import numpy as np


class BlowUp(RuntimeError):
    """A simulation became unstable; names the sim, the frame and the cause."""

    def __init__(self, sim: str, frame: int, cause: str):
        self.sim, self.frame, self.cause = sim, frame, cause
        super().__init__(f"simulation {sim} blew up at frame {frame}: {cause}")


def overlap_fractions(x: np.ndarray, radius: np.ndarray, kinematic: np.ndarray) -> np.ndarray:
    """Every positive overlap r_i + r_j - |x_i - x_j| of a frame, divided by the pair's smaller radius.

    Pairs of two kinematic particles are ignored (their overlap is part of the geometry).
    """
    # imported here, not at the top: the workflow imports this module to plan its jobs
    from scipy.spatial import cKDTree

    tree = cKDTree(x)
    pairs = tree.query_pairs(2.0 * float(radius.max()), output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros(0)
    i, j = pairs[:, 0], pairs[:, 1]
    keep = ~(kinematic[i] & kinematic[j])
    i, j = i[keep], j[keep]
    overlap = (radius[i] + radius[j] - np.linalg.norm(x[i] - x[j], axis=1)) / np.minimum(radius[i], radius[j])
    return overlap[overlap > 0]


def max_overlap_fraction(x: np.ndarray, radius: np.ndarray, kinematic: np.ndarray) -> float:
    """Largest overlap r_i + r_j - |x_i - x_j| over pairs, divided by the smaller radius (0 without contact).

    Pairs of two kinematic particles are ignored (their overlap is part of the geometry).
    """
    overlaps = overlap_fractions(x, radius, kinematic)
    return float(overlaps.max()) if len(overlaps) else 0.0


def _box(corner) -> str:
    """A box corner as plain numbers, e.g. [-0.016, 0, 0.06]."""
    return "[" + ", ".join(f"{float(v):g}" for v in np.asarray(corner, float)) + "]"


def check_trajectory(sim: str, position: np.ndarray, radius: np.ndarray, kinematic: np.ndarray,
                     lower: np.ndarray, upper: np.ndarray, max_overlap: float) -> None:
    """Raise BlowUp at the first frame with a non-finite value, an escape or a large overlap."""
    radius = np.asarray(radius, float)
    kinematic = np.asarray(kinematic, bool)
    for frame, x in enumerate(np.asarray(position, float)):
        if not np.all(np.isfinite(x)):
            bad = int(np.argwhere(~np.isfinite(x))[0, 0])
            raise BlowUp(sim, frame, f"non-finite position of particle {bad}")
        outside = np.any((x < lower) | (x > upper), axis=1)
        if outside.any():
            p = int(np.argmax(outside))
            raise BlowUp(sim, frame, f"particle {p} left the domain {_box(lower)}-{_box(upper)} "
                                     f"(at {np.round(x[p], 3).tolist()})")
        frac = max_overlap_fraction(x, radius, kinematic)
        if frac > max_overlap:
            raise BlowUp(sim, frame, f"overlap of {frac:.3f} radii exceeds the limit {max_overlap}")


def check_energy(sim: str, kinetic: np.ndarray, potential: np.ndarray, scale: float, max_gain: float) -> None:
    """Raise BlowUp at the first frame whose mechanical energy (kinetic + gravitational) exceeds the
    first frame's by more than ``max_gain * scale``.

    A granular flow under gravity only dissipates: its kinetic plus potential energy never grows
    (the elastic energy of the contacts is a small fraction of ``scale``). Growth means the
    integrator is injecting energy: the hallmark of a time step above the stable limit.
    """
    energy = np.asarray(kinetic, float) + np.asarray(potential, float)
    gain = (energy - energy[0]) / scale
    bad = np.flatnonzero(~np.isfinite(gain) | (gain > max_gain))
    if len(bad):
        f = int(bad[0])
        raise BlowUp(sim, f, f"mechanical energy grew by {gain[f]:.3g} x the reference energy {scale:.4g} J "
                             f"since frame 0 with no energy source (limit {max_gain})")


def check_energy_of(setup, position: np.ndarray, mass: np.ndarray, radius: np.ndarray, kinetic: np.ndarray) -> None:
    """The energy check of a recorded run of ``setup`` (a generators.dem.Setup whose
    ``max_energy_gain`` is set): kinetic (the engine's, translational + rotational) plus gravitational
    energy of the moving particles, gravity along -axis D, in units of M g d (M the moving mass, d the
    mean moving diameter)."""
    moving = ~setup.kinematic
    m = np.asarray(mass)[moving]
    potential = setup.gravity * (np.asarray(position)[:, moving, -1] * m).sum(axis=1)
    scale = setup.gravity * m.sum() * 2.0 * np.asarray(radius)[moving].mean()
    check_energy(setup.name, kinetic, potential, scale, setup.max_energy_gain)
