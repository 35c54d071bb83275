"""The 2D landslide scene (article 5.1 "Slide"), independent of the engine that runs it.

A bedrock slope of fixed boundary particles carries a soil mass in three layers. A band dipping
downslope (the middle layer) is made of sliding-prone soil: at the trigger its friction drops
and the soil above it slides down the slope. Species ids: 0 bedrock (kinematic), 1 stable soil,
2 sliding-prone soil.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from generators import contact
from generators.scenes import packing

BEDROCK, STABLE, WEAK = 0, 1, 2
SPECIES_NAMES = {BEDROCK: "bedrock", STABLE: "stable soil", WEAK: "sliding-prone soil"}
WEAK_REFERENCE_X = 40.0   # m, where the weak layer's base height is measured

# Parameters that shape the settled packing: a change in any of them makes a new packing.
PACKING_KEYS = (
    "domain", "gravity", "bedrock_profile", "soil_surface", "bedrock_radius", "radius",
    "density", "young", "kt_over_kn", "restitution", "friction", "rolling_friction",
    "dt_safety", "dt", "settle_time", "settle_damping", "settle_speed", "max_overlap",
)


def polyline_y(points: list[list[float]], x: np.ndarray) -> np.ndarray:
    """Height of a polyline [[x, y], ...] at ``x`` (flat extrapolation beyond its ends)."""
    pts = np.asarray(points, float)
    return np.interp(x, pts[:, 0], pts[:, 1])


def packing_params(cfg: dict, index: int) -> dict:
    """The packing-relevant parameters of packing ``index`` (its seed included)."""
    return packing.packing_params(cfg, PACKING_KEYS, index)


@dataclass(frozen=True)
class Particles:
    """Particles of a scene before or after settling."""

    x: np.ndarray        # [N, 2]
    radius: np.ndarray   # [N]
    species: np.ndarray  # [N] int

    @property
    def kinematic(self) -> np.ndarray:
        return self.species == BEDROCK


def bedrock_particles(cfg: dict) -> tuple[np.ndarray, np.ndarray]:
    """Fixed particles along the bedrock profile and up the two side walls."""
    rb = cfg["bedrock_radius"]
    width, height = cfg["domain"]
    spacing = 1.8 * rb           # neighbours overlap a little: no soil particle falls through
    pts = np.asarray(cfg["bedrock_profile"], float)
    centres = []
    for (x0, y0), (x1, y1) in zip(pts[:-1], pts[1:], strict=True):
        length = math.hypot(x1 - x0, y1 - y0)
        n = max(1, int(math.ceil(length / spacing)))
        s = np.arange(n) / n
        centres.append(np.stack([x0 + s * (x1 - x0), y0 + s * (y1 - y0)], axis=1))
    centres.append(pts[-1:])
    profile = np.concatenate(centres)
    profile[:, 0] = np.clip(profile[:, 0], rb, width - rb)
    profile[:, 1] = np.clip(profile[:, 1], rb, height - rb)
    top = max(np.max(np.asarray(cfg["soil_surface"])[:, 1]), pts[:, 1].max()) + 4 * rb
    walls = []
    for x_wall, y_base in ((rb, pts[0, 1]), (width - rb, pts[-1, 1])):
        ys = np.arange(y_base + spacing, min(top, height - rb), spacing)
        walls.append(np.stack([np.full_like(ys, x_wall), ys], axis=1))
    xy = np.concatenate([profile, *walls])
    return xy, np.full(len(xy), rb)


def loose_packing(cfg: dict, seed: int) -> Particles:
    """Soil discs on a jittered triangular lattice filling the nominal soil region, plus bedrock.

    The lattice spacing is one maximum diameter, so nothing overlaps; settling under gravity
    (the prepare stage) compacts the mass.
    """
    rng = np.random.default_rng(seed)
    r_min, r_max = cfg["radius"]
    rb = cfg["bedrock_radius"]
    width, _ = cfg["domain"]
    bed_xy, bed_r = bedrock_particles(cfg)
    spacing = 2.0 * r_max * 1.02
    row_h = spacing * math.sqrt(3) / 2
    soil = []
    y_min = float(np.min(np.asarray(cfg["bedrock_profile"])[:, 1]))
    y_max = float(np.max(np.asarray(cfg["soil_surface"])[:, 1]))
    for row, y in enumerate(np.arange(y_min + rb + r_max, y_max, row_h)):
        xs = np.arange(2 * rb + r_max + (row % 2) * spacing / 2, width - 2 * rb - r_max, spacing)
        keep = (y >= polyline_y(cfg["bedrock_profile"], xs) + rb + r_max * 1.05) & (
            y <= polyline_y(cfg["soil_surface"], xs))
        soil.extend((x, y) for x in xs[keep])
    soil_xy = np.asarray(soil, float).reshape(-1, 2)
    radius = rng.uniform(r_min, r_max, len(soil_xy))
    slack = np.maximum(spacing / 2 - radius, 0.0)
    angle = rng.uniform(0, 2 * math.pi, len(soil_xy))
    soil_xy += (0.9 * slack * rng.uniform(0, 1, len(soil_xy)))[:, None] * np.stack(
        [np.cos(angle), np.sin(angle)], axis=1)
    return Particles(
        x=np.concatenate([bed_xy, soil_xy]),
        radius=np.concatenate([bed_r, radius]),
        species=np.concatenate([np.full(len(bed_xy), BEDROCK), np.full(len(soil_xy), STABLE)]),
    )


def assign_layers(particles: Particles, weak_base: float, weak_thickness: float,
                  weak_dip: float) -> np.ndarray:
    """Species of every particle once the three layers are set (the trigger).

    The weak (middle) layer lies between y_low(x) = weak_base - tan(dip) (x - 40 m) and
    y_low(x) + weak_thickness; soil above and below it is stable.
    """
    species = particles.species.copy()
    x, y = particles.x[:, 0], particles.x[:, 1]
    y_low = weak_base - math.tan(math.radians(weak_dip)) * (x - WEAK_REFERENCE_X)
    weak = (species != BEDROCK) & (y >= y_low) & (y < y_low + weak_thickness)
    species[weak] = WEAK
    return species


dem_step = contact.disc_time_step      # bedrock is fixed: the limit is at two of the smallest soil discs
