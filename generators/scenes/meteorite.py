"""The 2D meteorite impact scene (article 5.1 "Meteorite Impact"), independent of the engine.

A granular ground bed, settled once under gravity between fixed side and bottom walls (the
prepare stage), is struck by a meteorite: a disc-shaped cluster of touching particles, so that
it breaks into debris on impact. Species ids: 0 ground, 1 meteorite. No particle is kinematic:
the walls are the engine's planar walls and enter the surrogate through its boundary features.

The meteorite flies in the x-y plane at ``angle`` degrees below the horizontal (90: straight
down), moving towards +x, and its path is aimed so that it first touches the bed surface at
``contact_frame`` frames after frame 0 above the middle of the domain.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from generators import contact
from generators.scenes import packing

GROUND, METEORITE = 0, 1
SPECIES_NAMES = {GROUND: "ground", METEORITE: "meteorite"}

# Parameters that shape the settled bed: a change in any of them makes a new packing.
PACKING_KEYS = (
    "domain", "gravity", "radius", "bed_depth", "density", "young", "kt_over_kn", "restitution",
    "friction", "rolling_friction", "dt_safety", "dt", "settle_time", "settle_damping", "settle_speed",
    "max_overlap",
)


def packing_params(cfg: dict, index: int = 0) -> dict:
    return packing.packing_params(cfg, PACKING_KEYS, index)


def packings(cfg: dict) -> list[dict]:
    """Every packing the scene's sweep uses: one bed, shared by every sim."""
    return [packing_params(cfg, 0)]


@dataclass(frozen=True)
class Particles:
    x: np.ndarray        # [N, 2]
    radius: np.ndarray   # [N]
    species: np.ndarray  # [N]


def loose_bed(cfg: dict, seed) -> Particles:
    """Ground discs on a jittered triangular lattice filling the domain's width up to 1.3 bed depths.

    The lattice spacing is one maximum diameter, so nothing overlaps; settling compacts the bed to
    about ``bed_depth``.
    """
    rng = np.random.default_rng(seed)
    r_min, r_max = cfg["radius"]
    width, _ = cfg["domain"]
    spacing = 2.0 * r_max * 1.02
    row_h = spacing * math.sqrt(3) / 2
    xy = []
    for row, y in enumerate(np.arange(r_max, 1.3 * cfg["bed_depth"], row_h)):
        xs = np.arange(r_max + (row % 2) * spacing / 2, width - r_max, spacing)
        xy.extend((x, y) for x in xs)
    xy = np.asarray(xy, float)
    radius = rng.uniform(r_min, r_max, len(xy))
    slack = np.maximum(spacing / 2 - radius, 0.0)
    angle = rng.uniform(0, 2 * math.pi, len(xy))
    xy += (0.9 * slack * rng.uniform(0, 1, len(xy)))[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    return Particles(xy, radius, np.full(len(xy), GROUND))


def meteorite_cluster(cfg: dict) -> tuple[np.ndarray, float]:
    """Centres (relative to the cluster's centre) and radius of the meteorite's particles: a
    triangular lattice of touching discs of the mean ground radius inside a disc of
    ``meteorite_radius``."""
    r = 0.5 * (cfg["radius"][0] + cfg["radius"][1])
    big = cfg["meteorite_radius"]
    if big < r:
        raise ValueError(f"meteorite_radius = {big} m is smaller than one particle radius ({r} m)")
    spacing = 2.0 * r
    row_h = spacing * math.sqrt(3) / 2
    n = int(math.ceil(big / row_h)) + 1
    pts = []
    for j in range(-n, n + 1):
        for i in range(-n - 1, n + 2):
            x, y = (i + 0.5 * (j % 2)) * spacing, j * row_h
            if math.hypot(x, y) + r <= big + 1e-9:
                pts.append((x, y))
    pts = np.asarray(pts, float)
    return pts - pts.mean(axis=0), r


def surface_height(bed: Particles, x: float, half_width: float) -> float:
    """Top of the bed (max y + r of ground particles) within ``half_width`` of ``x``."""
    near = np.abs(bed.x[:, 0] - x) <= half_width
    if not near.any():
        raise ValueError(f"no ground particle within {half_width} m of x = {x} m")
    return float(np.max(bed.x[near, 1] + bed.radius[near]))


def place_meteorite(row: dict, bed: Particles) -> tuple[Particles, np.ndarray]:
    """The bed plus the meteorite of sweep row ``row``, and the meteorite's initial velocity [2].

    The cluster's lowest point reaches the height of the bed's top above x = domain/2 after
    ``contact_frame`` frame intervals of straight flight (gravity bends the path by g t^2 / 2, a few
    centimetres).
    """
    offsets, r = meteorite_cluster(row)
    theta = math.radians(row["angle"])
    direction = np.array([math.cos(theta), -math.sin(theta)])
    velocity = row["speed"] * direction
    width, height = row["domain"]
    x_hit = 0.5 * width
    y_top = surface_height(bed, x_hit, 2.0 * row["radius"][1])
    lowest = float(np.max(r - offsets[:, 1]))          # the cluster's lowest point below its centre
    centre_at_contact = np.array([x_hit, y_top + lowest])
    flight = row["contact_frame"] * row["frame_interval"] * row["speed"]
    centre = centre_at_contact - direction * flight
    xy = centre + offsets
    if (xy[:, 1] + r > height).any() or (xy[:, 0] - r < 0).any():
        raise ValueError(f"{row.get('id', 'meteorite')}: the meteorite starts outside the domain {row['domain']} "
                         f"(centre {np.round(centre, 2).tolist()}); lower contact_frame or speed")
    return (Particles(np.concatenate([bed.x, xy]), np.concatenate([bed.radius, np.full(len(xy), r)]),
                      np.concatenate([bed.species, np.full(len(xy), METEORITE)])), velocity)


dem_step = contact.disc_time_step
