"""The 3D direct-shear scene (article 5.1 "Direct Shear"): definition, DEM description and metrics
(Table 4, Fig. 14).

A shear box (inner size ``box`` = L x W x H) split at mid-height ``z_s = H / 2``; its bottom and
side walls are spheres ("box" particles, kinematic): the lower half, bottom plate included, moves
along +x at constant speed, the upper half is held. Soil spheres fill it. The soil's Young's
modulus is swept; it is the per-particle property ``young`` of the data (box particles are of the
soil's material, so they carry the same value). Species ids: 0 box (kinematic), 1 soil.

Geometry: the box's inner faces are the planes x = 0, x = L, y = 0, y = W and z = 0; wall sphere
centres lie one wall radius outside them on a square grid of spacing ``wall_spacing`` radii.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from generators import contact, dem
from generators.config import ConfigError
from generators.scene import Scene, lattice_count, lattice_spacing, trajectory_parameters

BOX, SOIL = 0, 1
LOWER = "lower"            # the packing's group of box spheres in the moving lower half
FILL_FACTOR = 2.0          # the loose soil is poured up to this many box heights, then trimmed at H
SETTLE_CHECK = 0.005       # s of physical time between two checks of the settling energy


def split_height(cfg: dict) -> float:
    return 0.5 * float(cfg["box"][2])


def young_values(cfg: dict) -> list[float]:
    """The swept moduli: ``sweep.n_young`` values spaced evenly in log between ``sweep.young``."""
    lo, hi = cfg["sweep"]["young"]
    n = int(cfg["sweep"]["n_young"])
    values = np.geomspace(lo, hi, n) if n > 1 else np.array([math.sqrt(lo * hi)])
    return [float(f"{v:.6g}") for v in values]


def _grid(a0: float, a1: float, step: float) -> np.ndarray:
    n = max(1, int(math.ceil((a1 - a0) / step)))
    return np.linspace(a0, a1, n + 1)


def box_particles(cfg: dict, height: float) -> dem.Particles:
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
    return dem.Particles(xyz, np.full(len(xyz), rw), np.full(len(xyz), BOX), {LOWER: xyz[:, 2] < split_height(cfg)})


def loose_soil(cfg: dict, seed) -> dem.Particles:
    """Soil spheres on a jittered cubic lattice filling the box up to FILL_FACTOR box heights."""
    rng = np.random.default_rng(seed)
    r_min, r_max = cfg["radius"]
    length, width, height = cfg["box"]
    spacing = lattice_spacing(r_max)
    axes = [np.arange(r_max, extent - r_max + 1e-12, spacing) for extent in (length, width, FILL_FACTOR * height)]
    xyz = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    radius = rng.uniform(r_min, r_max, len(xyz))
    slack = np.maximum(spacing / 2 - radius, 0.0)
    xyz = xyz + rng.uniform(-1, 1, xyz.shape) * (0.5 * slack)[:, None]
    return dem.Particles(xyz, radius, np.full(len(xyz), SOIL), {LOWER: np.zeros(len(xyz), bool)})


def loose_packing(cfg: dict) -> dem.Particles:
    box = box_particles(cfg, FILL_FACTOR * cfg["box"][2])
    soil = loose_soil(cfg, [cfg["seed"], int(round(math.log10(cfg["young"]) * 1000))])
    return box.concat(soil)


def check_filled(settled: dem.Particles, cfg: dict, where: str) -> None:
    """Refuse a settled pour whose soil does not reach the box height H: trimming it would leave the box
    under-filled (and the sets above the split plane thin or empty)."""
    soil = settled.species == SOIL
    top = float((settled.x[soil, 2] + settled.radius[soil]).max())
    if top < cfg["box"][2]:
        raise ValueError(f"{where}: the settled soil reaches z = {top:.4g} m, below the box height "
                         f"H = {cfg['box'][2]:.4g} m (config 'shear.box'); the pour of {FILL_FACTOR:g} box heights "
                         "settled too low: use smaller soil spheres ('shear.radius') or a lower box")


def trim(settled: dem.Particles, cfg: dict) -> dem.Particles:
    """The settled packing cut to the box: soil whose top is above H and wall rows above H removed."""
    height = cfg["box"][2]
    soil = settled.species == SOIL
    keep = np.where(soil, settled.x[:, 2] + settled.radius <= height, settled.x[:, 2] <= height + 1e-9)
    return settled.subset(keep)


def domain(cfg: dict, displacement: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounds every particle must stay within: the box walls, shifted by the shear, plus a margin
    of two wall diameters, and up to two box heights."""
    length, width, height = cfg["box"]
    margin = 4.0 * cfg["wall_radius"]
    return (np.array([-margin, -margin, -margin]),
            np.array([length + displacement + margin, width + margin, 2.0 * height]))

@dataclass
class ShearMetrics:
    """Error sets around the failure surface (the box split plane z_s) and the mean soil x-position.

    Sets are fixed by the frame-0 heights: Above z_s < z <= z_s + band, Below z_s - band <= z < z_s,
    Failure Surface both, All every soil (moving) particle.
    """

    kinematic: np.ndarray        # [N] bool
    height0: np.ndarray          # [N] m, z at frame 0
    split_height: float          # m
    band: float                  # m, half-width of the failure-surface sets (config shear.failure_band)

    names = ("Mean x",)
    sets = ("Above", "Below", "Failure Surface", "All")
    pair_names = tuple(f"{s} {k}" for s in sets for k in ("sum", "mean"))
    units = {"Mean x": "m", **{name: "m" for name in pair_names}}

    @classmethod
    def for_trajectory(cls, traj, body_displacement: float | None = None) -> ShearMetrics:
        split, band = trajectory_parameters(traj, ("split_height", "failure_band"), "shear")
        return cls(np.asarray(traj.kinematic, bool), np.asarray(traj.position[0, :, 2], float), split, band)

    def members(self) -> dict[str, np.ndarray]:
        soil, z, zs = ~self.kinematic, self.height0, self.split_height
        above = soil & (z > zs) & (z <= zs + self.band)
        below = soil & (z >= zs - self.band) & (z < zs)
        return {"Above": above, "Below": below, "Failure Surface": above | below, "All": soil}

    def __call__(self, position: np.ndarray) -> dict[str, np.ndarray]:
        """Per frame: the mean x of the soil particles (m); NaN on a non-finite frame."""
        x = np.asarray(position, np.float64)[:, ~self.kinematic, 0]
        return {"Mean x": x.mean(axis=1)}

    def compare(self, predicted: np.ndarray, truth: np.ndarray) -> dict[str, np.ndarray]:
        """Per frame and set: sum and mean of |p_pred - p_true| (m); NaN for an empty set, +inf where
        a predicted soil position is non-finite (a blow-up is an infinite error)."""
        dist = np.linalg.norm(np.asarray(predicted, np.float64) - np.asarray(truth, np.float64), axis=-1)
        broken = ~np.isfinite(np.asarray(predicted, np.float64)[:, ~self.kinematic]).all(axis=(1, 2))
        out = {}
        for name, mask in self.members().items():
            total = dist[:, mask].sum(axis=1) if mask.any() else np.full(len(dist), np.nan)
            mean = total / mask.sum() if mask.any() else np.full(len(dist), np.nan)
            total[broken], mean[broken] = np.inf, np.inf
            out[f"{name} sum"], out[f"{name} mean"] = total, mean
        return out


def dem_step(cfg: dict, where: str) -> tuple[float, float, float]:
    """(dt, stable limit, kn) of the soil contact at the sim's modulus (contact.time_step)."""
    return contact.time_step(cfg, where, 3)


class Shear(Scene):
    name = "shear"
    dim = 3
    species = {BOX: "box", SOIL: "soil"}
    kinematic_species = (BOX,)
    engines = ("yade", "lammps")
    metrics = ShearMetrics
    log_scaled_properties = ("young",)

    def packings(self, cfg: dict) -> list[dict]:
        """The one packing every sim shares: settled with the stiffest swept modulus.

        Under self-weight the overlaps are below 1e-4 radii at every modulus of the sweep, so the
        geometry barely depends on it; settling at the stiffest keeps overlaps smallest, and a softer
        sim starts by sagging a few micrometres (never by springing apart).
        """
        return [self.packing_params(cfg, young=float(max(young_values(cfg))))]

    def _axes(self, cfg: dict) -> list[tuple[float, float]]:
        return [(e, float(d)) for e in young_values(cfg) for d in cfg["sweep"]["displacements"]]

    def sweep_size(self, cfg: dict) -> int:
        return len(young_values(cfg)) * len(cfg["sweep"]["displacements"])

    def draw(self, cfg: dict, index: int, rng: np.random.Generator, packings: list[str]) -> dict:
        """The soil modulus x shear displacement grid, modulus varying slowest; one shared packing."""
        young, displacement = self._axes(cfg)[index]
        return {"young": young, "displacement": displacement, "packing": packings[0]}

    def finish_sweep(self, rows: list[dict], cfg: dict) -> None:
        """``domain_displacement``, the largest displacement, fixes the same data bounds for every sim."""
        for row in rows:
            row["domain_displacement"] = max(float(d) for d in cfg["sweep"]["displacements"])

    def settle_setup(self, params: dict) -> dem.Setup:
        """The loose soil poured into the box (walls extended upwards)."""
        name = f"packing E = {params['young']:g} Pa"
        return self.setup(params, name, loose_packing(params), dem_step(params, name), domain(params, 0.0),
                          self.settling(params, "viscous", SETTLE_CHECK))

    def settled(self, params: dict, particles: dem.Particles, where: str) -> dem.Particles:
        """The settled pour, refused if under-filled, trimmed at the box height."""
        check_filled(particles, params, where)
        return trim(particles, params)

    def simulate_setup(self, row: dict, packing: dem.Particles) -> dem.Setup:
        """The lower box moves along +x at a speed that gives exactly ``displacement`` at the last frame."""
        def record(dt: float) -> dem.Record:
            interval = row["displacement"] / (row["shear_speed"] * (row["frames"] - 1))
            return dem.Record(start=0, every=max(1, int(round(interval / dt))), frames=row["frames"])

        step = dem_step(row, where=row["id"])
        dt = step[0]
        every = record(dt).every
        speed = row["displacement"] / (every * dt * (row["frames"] - 1))
        box_lower, box_upper = domain(row, row["domain_displacement"])
        return self.setup(row, row["id"], packing, step, domain(row, row["displacement"]), record,
                      motions=(dem.Motion(LOWER, (speed, 0.0, 0.0)),), box_lower=box_lower, box_upper=box_upper)

    def h5md_parameters(self, row: dict, setup: dem.Setup) -> dict:
        return {"split_height": split_height(row), "shear_speed": setup.motions[0].velocity[0]}

    def properties(self, row: dict) -> dict[str, float]:
        return {"young": row["young"]}

    def particle_estimate(self, cfg: dict) -> int:
        """Lattice sites of the loose pour (FILL_FACTOR box heights) plus the box's wall spheres."""
        length, width, height = cfg["box"]
        step = cfg["wall_spacing"] * cfg["wall_radius"]
        walls = (length * width + 2 * (length + width) * FILL_FACTOR * height) / step ** 2
        return int(lattice_count(length * width * FILL_FACTOR * height, cfg["radius"][1], 3) + walls)

    def check(self, cfg: dict) -> None:
        from generators.scene import check_range
        check_range(self.name, "sweep.young", cfg["sweep"]["young"])
        if cfg["wall_radius"] * (cfg["wall_spacing"] / 2**0.5 - 1.0) >= cfg["radius"][0]:
            raise ConfigError(f"config keys 'shear.wall_radius' = {cfg['wall_radius']} and 'shear.wall_spacing' = "
                              f"{cfg['wall_spacing']} leave holes in the box walls wider than the smallest soil "
                              f"sphere ({cfg['radius'][0]} m): lower the spacing or raise the wall radius")


SCENE = Shear()
