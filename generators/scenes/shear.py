"""The 3D direct-shear scene (article 5.1 "Direct Shear"), independent of the engine.

A shear box (inner size ``box`` = L x W x H) split at mid-height ``z_s = H / 2``; its bottom and
side walls are spheres ("box" particles, kinematic): the lower half, bottom plate included, moves
along +x at constant ``shear_speed``, the upper half is held. Soil spheres fill it. The soil's
Young's modulus is swept; it is the per-particle property ``young`` of the data (box particles
are of the soil's material, so they carry the same value). Species ids: 0 box (kinematic), 1 soil.

Geometry: the box's inner faces are the planes x = 0, x = L, y = 0, y = W and z = 0; wall sphere
centres lie one wall radius outside them on a square grid of spacing ``wall_spacing`` radii.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from generators import contact
from generators.scenes import packing

BOX, SOIL = 0, 1
SPECIES_NAMES = {BOX: "box", SOIL: "soil"}
FILL_FACTOR = 2.0          # the loose soil is poured up to this many box heights, then trimmed at H

PACKING_KEYS = ("box", "gravity", "radius", "wall_radius", "wall_spacing", "density", "kt_over_kn",
                "restitution", "friction", "dt_safety", "dt", "settle_time", "settle_damping", "settle_speed",
                "max_overlap")


def split_height(cfg: dict) -> float:
    return 0.5 * float(cfg["box"][2])


def young_values(cfg: dict) -> list[float]:
    """The swept moduli: ``sweep.n_young`` values spaced evenly in log between ``sweep.young``."""
    lo, hi = cfg["sweep"]["young"]
    n = int(cfg["sweep"]["n_young"])
    values = np.geomspace(lo, hi, n) if n > 1 else np.array([math.sqrt(lo * hi)])
    return [float(f"{v:.6g}") for v in values]


def packing_params(cfg: dict, young: float) -> dict:
    return packing.packing_params(cfg, PACKING_KEYS, young=float(young))


def packings(cfg: dict) -> list[dict]:
    """The one packing every sim shares: settled with the stiffest swept modulus.

    Under self-weight the overlaps are below 1e-4 radii at every modulus of the sweep, so the
    geometry barely depends on it; settling at the stiffest keeps overlaps smallest, and a softer
    sim starts by sagging a few micrometres (never by springing apart).
    """
    return [packing_params(cfg, max(young_values(cfg)))]


@dataclass(frozen=True)
class Particles:
    x: np.ndarray        # [N, 3]
    radius: np.ndarray   # [N]
    species: np.ndarray  # [N]
    lower: np.ndarray    # [N] bool: box particle of the moving lower half

    def subset(self, keep: np.ndarray) -> Particles:
        return Particles(self.x[keep], self.radius[keep], self.species[keep], self.lower[keep])


def _grid(a0: float, a1: float, step: float) -> np.ndarray:
    n = max(1, int(math.ceil((a1 - a0) / step)))
    return np.linspace(a0, a1, n + 1)


def box_particles(cfg: dict, height: float) -> Particles:
    """Wall spheres of the bottom plate and the four side walls, up to ``height``."""
    length, width, _ = cfg["box"]
    rw = cfg["wall_radius"]
    step = cfg["wall_spacing"] * rw
    xs, ys = _grid(-rw, length + rw, step), _grid(-rw, width + rw, step)
    zs = _grid(-rw, height, step)[1:]
    pts = [np.stack(np.meshgrid(xs, ys, [-rw], indexing="ij"), -1).reshape(-1, 3)]
    for x in (-rw, length + rw):
        pts.append(np.stack(np.meshgrid([x], ys, zs, indexing="ij"), -1).reshape(-1, 3))
    for y in (-rw, width + rw):
        pts.append(np.stack(np.meshgrid(xs[1:-1], [y], zs, indexing="ij"), -1).reshape(-1, 3))
    xyz = np.concatenate(pts)
    return Particles(xyz, np.full(len(xyz), rw), np.full(len(xyz), BOX), xyz[:, 2] < split_height(cfg))


def loose_soil(cfg: dict, seed) -> Particles:
    """Soil spheres on a jittered cubic lattice filling the box up to FILL_FACTOR box heights."""
    rng = np.random.default_rng(seed)
    r_min, r_max = cfg["radius"]
    length, width, height = cfg["box"]
    spacing = 2.0 * r_max * 1.02
    axes = [np.arange(r_max, extent - r_max + 1e-12, spacing) for extent in (length, width, FILL_FACTOR * height)]
    xyz = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    radius = rng.uniform(r_min, r_max, len(xyz))
    slack = np.maximum(spacing / 2 - radius, 0.0)
    xyz = xyz + rng.uniform(-1, 1, xyz.shape) * (0.5 * slack)[:, None]
    return Particles(xyz, radius, np.full(len(xyz), SOIL), np.zeros(len(xyz), bool))


def loose_packing(cfg: dict) -> Particles:
    box = box_particles(cfg, FILL_FACTOR * cfg["box"][2])
    soil = loose_soil(cfg, [cfg["seed"], int(round(math.log10(cfg["young"]) * 1000))])
    return Particles(np.concatenate([box.x, soil.x]), np.concatenate([box.radius, soil.radius]),
                     np.concatenate([box.species, soil.species]), np.concatenate([box.lower, soil.lower]))


def check_filled(settled: Particles, cfg: dict, where: str) -> None:
    """Refuse a settled pour whose soil does not reach the box height H: trimming it would leave the box
    under-filled (and the sets above the split plane thin or empty)."""
    soil = settled.species == SOIL
    top = float((settled.x[soil, 2] + settled.radius[soil]).max())
    if top < cfg["box"][2]:
        raise ValueError(f"{where}: the settled soil reaches z = {top:.4g} m, below the box height "
                         f"H = {cfg['box'][2]:.4g} m (config 'shear.box'); the pour of {FILL_FACTOR:g} box heights "
                         "settled too low: use smaller soil spheres ('shear.radius') or a lower box")


def trim(settled: Particles, cfg: dict) -> Particles:
    """The settled packing cut to the box: soil whose top is above H and wall rows above H removed."""
    height = cfg["box"][2]
    soil = settled.species == SOIL
    keep = np.where(soil, settled.x[:, 2] + settled.radius <= height, settled.x[:, 2] <= height + 1e-9)
    return settled.subset(keep)


def dem_step(cfg: dict, where: str) -> tuple[float, float, float]:
    """(dt, stable limit, kn) of the soil contact at the smallest sphere.

    kn = 2 E r1 r2 / (r1 + r2) (YADE's ViscElMat from Young's modulus) is E r_min for two of the
    smallest spheres, the stiffest oscillator relative to its mass: dt_crit = 2 / sqrt(2 kn / m_min).
    """
    kn = cfg["young"] * cfg["radius"][0]
    limit = contact.stable_time_step(contact.sphere_mass(cfg["density"], cfg["radius"][0]), kn)
    return contact.choose_time_step(limit, cfg["dt_safety"], cfg["dt"], where), limit, kn


def domain(cfg: dict, displacement: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounds every particle must stay within: the box walls, shifted by the shear, plus a margin
    of two wall diameters, and up to two box heights."""
    length, width, height = cfg["box"]
    margin = 4.0 * cfg["wall_radius"]
    return (np.array([-margin, -margin, -margin]),
            np.array([length + displacement + margin, width + margin, 2.0 * height]))
