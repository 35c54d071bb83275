"""The DEM ensemble: members of a test sim restarted where the surrogate starts (docs/data.md, DEM ensemble).

Member j of a sim repeats the sim's run (same deck or script, packing, engine, ranks and threads) up to its last
history frame K - 1, where every moving particle is displaced by a normal draw per axis (seeded by the sim's seed
and j; in-plane in 2D scenes), and runs on from there to the end of the window. A deterministic replay reaches the
sim's own state at frame K - 1 (positions, velocities, rotations, contact history) without a restart file, and
that it did is checked where a member is read (evaluation/stored.py): its frames 0..K-1 must equal the sim's
stored frames bit for bit.

The displacement's standard deviation per axis (:func:`displacement_std`) is the configured
``evaluate.ensemble_perturbation`` radii of each particle, but never below the rounding of the stored positions
(float32: half its spacing at the box's largest coordinate), so that a member differs from its sim by at least
what storing the sim already changed.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from generators import dem

#: the sweep-row keys of a member: its index j, the frame it is perturbed after, the size in radii
MEMBER, FRAME, SIZE = "ensemble_member", "perturb_frame", "perturbation"


def float32_floor(box_lower, box_upper) -> float:
    """Half the float32 spacing at the largest |coordinate| of the box: the rounding of a stored position (m)."""
    corner = float(np.max(np.abs(np.concatenate([np.ravel(box_lower), np.ravel(box_upper)]))))
    return 0.5 * float(np.spacing(np.float32(corner)))


def displacement_std(perturbation: float, radius: np.ndarray, box_lower, box_upper) -> np.ndarray:
    """The standard deviation per axis of each particle's displacement (m): ``perturbation`` x its radius, or
    the float32 rounding of the stored positions (:func:`float32_floor`) where that is larger."""
    return np.maximum(float(perturbation) * np.asarray(radius, float), float32_floor(box_lower, box_upper))


def draw(setup: dem.Setup, perturbation: float, seed: int, member: int) -> np.ndarray:
    """Member ``member``'s displacement [N, D] of the Setup's particles: a normal draw per axis of
    :func:`displacement_std` for each moving particle (seeded by the sim's ``seed`` and ``member``), zero for
    the kinematic ones. D is the scene's dimension, so 2D scenes move in their plane only."""
    lower, upper = setup.box
    std = displacement_std(perturbation, setup.particles.radius, lower, upper)
    rng = np.random.default_rng([int(seed), int(member)])
    moving = ~setup.kinematic
    out = np.zeros_like(np.asarray(setup.particles.x, float))
    out[moving] = rng.normal(0.0, 1.0, out[moving].shape) * std[moving, None]
    return out


def is_member(row: dict) -> bool:
    """Whether a sweep row is a DEM ensemble member's (it names the frame it is perturbed after)."""
    return row.get(FRAME) is not None


def member_setup(setup: dem.Setup, row: dict) -> dem.Setup:
    """The sim's Setup with member ``row[MEMBER]``'s perturbation after frame ``row[FRAME]``."""
    displacement = draw(setup, float(row[SIZE]), int(row["seed"]), int(row[MEMBER]))
    return dataclasses.replace(setup, perturbation=dem.Perturbation(int(row[FRAME]), displacement))


def parameters(setup: dem.Setup, row: dict) -> dict[str, float]:
    """What a member's H5MD /parameters add to its row (which names the member, the frame and the size in
    radii): the float32 floor and the smallest and largest standard deviation per axis used (m)."""
    lower, upper = setup.box
    std = displacement_std(float(row[SIZE]), setup.particles.radius, lower, upper)[~setup.kinematic]
    floor = float32_floor(lower, upper)
    return {"perturbation_floor": floor, "perturbation_std_min": float(std.min()) if std.size else floor,
            "perturbation_std_max": float(std.max()) if std.size else floor}
