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
    """Raise BlowUp at the first frame whose mechanical energy (kinetic + potential: gravitational and the
    contacts' elastic energy) exceeds the first frame's by more than ``max_gain * scale``.

    A granular flow under gravity only dissipates: its kinetic plus potential energy never grows. Growth means
    the integrator is injecting energy: the hallmark of a time step above the stable limit. The elastic energy
    belongs in it: a column released from behind its gate turns the energy of its compressed contacts into
    motion (the paper preset's tallest column, 5053 discs 25 wide, stores 0.26 M g d at release; without its
    elastic energy the check read that as a gain of 0.13 M g d; docs/scenes/collapse.md).
    """
    energy = np.asarray(kinetic, float) + np.asarray(potential, float)
    gain = (energy - energy[0]) / scale
    bad = np.flatnonzero(~np.isfinite(gain) | (gain > max_gain))
    if len(bad):
        f = int(bad[0])
        raise BlowUp(sim, f, f"mechanical energy grew by {gain[f]:.3g} x the reference energy {scale:.4g} J "
                             f"since frame 0 with no energy source (limit {max_gain})")


def elastic_energy(x: np.ndarray, radius: np.ndarray, kinematic: np.ndarray, pair_kn, walls=(), wall_kn=0.0) -> float:
    """Normal elastic energy sum 1/2 kn delta^2 of one frame's contacts: every overlapping pair with a moving
    particle (``pair_kn(i, j)``: the pairs' stiffnesses, N/m) and every moving particle pressed into a planar wall
    (``walls``: generators.dem.PlanarWall, stiffness ``wall_kn``)."""
    from scipy.spatial import cKDTree

    x, radius, kinematic = np.asarray(x, float), np.asarray(radius, float), np.asarray(kinematic, bool)
    pairs = cKDTree(x).query_pairs(2.0 * float(radius.max()), output_type="ndarray")
    energy = 0.0
    if len(pairs):
        i, j = pairs[~(kinematic[pairs[:, 0]] & kinematic[pairs[:, 1]])].T
        delta = radius[i] + radius[j] - np.linalg.norm(x[i] - x[j], axis=1)
        pressed = delta > 0
        energy += float((0.5 * pair_kn(i[pressed], j[pressed]) * delta[pressed] ** 2).sum())
    moving = ~kinematic
    for wall in walls:
        for bound, sign in ((wall.lower, 1.0), (wall.upper, -1.0)):
            if bound is not None:
                delta = radius[moving] - sign * (x[moving, wall.axis] - bound)
                energy += float((0.5 * wall_kn * delta[delta > 0] ** 2).sum())
    return energy


def check_energy_of(setup, position: np.ndarray, mass: np.ndarray, radius: np.ndarray, kinetic: np.ndarray) -> None:
    """The energy check of a recorded run of ``setup`` (a generators.dem.Setup whose ``max_energy_gain`` is set):
    kinetic (the engine's, translational + rotational) plus gravitational energy of the moving particles, gravity
    along -axis D, plus the normal elastic energy of the contacts (:func:`elastic_energy`, each pair's stiffness
    from the setup's contacts), in units of M g d (M the moving mass, d the mean moving diameter)."""
    moving = ~setup.kinematic
    m = np.asarray(mass)[moving]
    position = np.asarray(position, float)
    species = np.asarray(setup.particles.species)
    kn = np.array([setup.species_contacts.get(s, setup.contact).kn for s in range(setup.n_species)])

    def pair_kn(i: np.ndarray, j: np.ndarray) -> np.ndarray:
        own = np.isin(species[i], list(setup.species_contacts))
        return np.where(own, kn[species[i]], kn[species[j]])

    elastic = np.array([elastic_energy(x, radius, setup.kinematic, pair_kn, setup.walls, setup.contact.kn)
                        for x in position])
    potential = setup.gravity * (position[:, moving, -1] * m).sum(axis=1) + elastic
    scale = setup.gravity * m.sum() * 2.0 * np.asarray(radius)[moving].mean()
    check_energy(setup.name, kinetic, potential, scale, setup.max_energy_gain)
