"""The 3D direct-shear scene (article 5.1 "Direct Shear"): definition, DEM description and metrics
(Table 4, Fig. 14).

A direct shear test under constant normal load. A shear box (inner size ``box`` = L x W x H) split at
mid-height ``z_s = H / 2``; its bottom and side walls are spheres ("box" particles, kinematic): the
lower half, bottom plate included, moves along +x at constant speed, the upper half is held. Soil
spheres fill it. On the soil rests a top platen: one layer of wall spheres ("platen", kinematic in the
data: its positions come from the engine) moving as one rigid body along z only, of mass
``platen_mass``, loaded so that it presses on the soil with ``normal_stress`` x L x W (its weight
included). The soil's Young's modulus and the normal stress are swept; they are the per-particle
properties ``young`` and ``normal_stress`` of the data (every particle carries the sim's values).
Species ids: 0 box (kinematic), 1 soil, 2 platen (kinematic).

A sim runs in two phases: loading (``load_time`` s: the platen's external force ramps up linearly over
its first half, the box is still), then shearing, which is the recorded window (frame 0 is its start).
Per frame the H5MD file holds the observables ``shear_force`` (N, the x contact force the soil exerts
on the held upper frame and on the platen, which is held in x with it, as a loading cap is in a shear
box: the shear resistance, positive along the shear), ``shear_stress`` (its value
over L W), ``shear_displacement`` (m, of the lower half), ``normal_stress`` (Pa, the z contact force
of the soil on the platen over L W) and ``normal_displacement`` (m, the platen's z change since frame
0; positive: dilation). A frame's forces are the mean over FORCE_SAMPLES equally spaced steps of the
frame interval ending at the frame (frame 0: the last interval of the loading), in both engines.

Geometry: the box's inner faces are the planes x = 0, x = L, y = 0, y = W and z = 0; wall sphere
centres lie one wall radius outside them on a square grid of spacing ``wall_spacing`` radii.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from generators import contact, dem
from generators.errors import ConfigError
from generators.scene import Scene, check_range, lattice_count, lattice_spacing, trajectory_parameters

BOX, SOIL, PLATEN = 0, 1, 2
LOWER = "lower"            # the packing's group of box spheres in the moving lower half
UPPER = "upper"            # the held upper half's box spheres (simulate only)
PLATEN_GROUP = "platen"    # the platen's spheres (simulate only)
PLATEN_CLEARANCE = 0.5     # wall radii between the platen's outer spheres and the box's inner faces
FORCE_SAMPLES = 10        # the forces of a frame: the mean of 10 equally spaced steps of its interval
# the per-frame observables (module docstring) and their SI units
OBSERVABLES = {"shear_force": "N", "shear_stress": "Pa", "shear_displacement": "m", "normal_stress": "Pa",
               "normal_displacement": "m"}
FILL_FACTOR = 2.0          # the loose soil is poured up to this many box heights, then trimmed at H


def split_height(cfg: dict) -> float:
    return 0.5 * float(cfg["box"][2])


def mean_diameter(cfg: dict) -> float:
    """The soil's nominal mean diameter d (m): twice the mean of the uniform ``radius`` range."""
    return float(cfg["radius"][0] + cfg["radius"][1])


def inertial_number(cfg: dict, speed: float, normal_stress: float) -> float:
    """The inertial number I = gamma_dot d sqrt(rho / sigma_n) of a shear at ``speed`` (m/s) under
    ``normal_stress`` (Pa), with the shear rate gamma_dot = v / H over the specimen height H (the box's) and d
    the nominal mean diameter (GDR MiDi 2004; da Cruz et al. 2005): quasi-static below about 1e-3."""
    rate = speed / float(cfg["box"][2])
    return rate * mean_diameter(cfg) * math.sqrt(float(cfg["density"]) / normal_stress)


def target_speed(cfg: dict, normal_stress: float) -> float:
    """The lower half's speed (m/s) under ``normal_stress``: ``shear_speed`` where set, else the fastest whose
    inertial number is ``max_inertial_number``, v = I_max H sqrt(sigma_n / rho) / d."""
    if cfg["shear_speed"] is not None:
        return float(cfg["shear_speed"])
    return (float(cfg["max_inertial_number"]) * float(cfg["box"][2]) * math.sqrt(normal_stress / float(cfg["density"]))
            / mean_diameter(cfg))


def slowest_speed(cfg: dict) -> float:
    """The slowest shear of the sweep (m/s): at its smallest normal stress (the longest frames)."""
    return min(target_speed(cfg, stress) for stress in normal_stress_values(cfg))


def frame_speed(row: dict, every: int, dt: float) -> float:
    """The lower half's speed (m/s) that gives the sim's displacement over its frames of ``every`` steps of ``dt``."""
    return row["displacement"] / (every * dt * (row["frames"] - 1))


def frame_steps(row: dict, dt: float) -> int:
    """DEM steps per recorded frame: the frame interval displacement / (speed (frames - 1)) in whole multiples of
    FORCE_SAMPLES steps, the nearest, or one multiple more where the nearest would shear faster than
    ``max_inertial_number`` allows."""
    speed = target_speed(row, row["normal_stress"])
    interval = row["displacement"] / (speed * (row["frames"] - 1))
    every = FORCE_SAMPLES * max(1, int(round(interval / (FORCE_SAMPLES * dt))))
    if inertial_number(row, frame_speed(row, every, dt), row["normal_stress"]) > row["max_inertial_number"]:
        every += FORCE_SAMPLES
    return every


def young_values(cfg: dict) -> list[float]:
    """The swept moduli: ``sweep.n_young`` values spaced evenly in log between ``sweep.young``."""
    lo, hi = cfg["sweep"]["young"]
    n = int(cfg["sweep"]["n_young"])
    values = np.geomspace(lo, hi, n) if n > 1 else np.array([math.sqrt(lo * hi)])
    return [float(f"{v:.6g}") for v in values]


def normal_stress_values(cfg: dict) -> list[float]:
    """The swept normal stresses: ``sweep.n_normal_stress`` values spaced evenly in log between
    ``sweep.normal_stress``."""
    lo, hi = cfg["sweep"]["normal_stress"]
    n = int(cfg["sweep"]["n_normal_stress"])
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


def platen_grid(cfg: dict) -> np.ndarray:
    """[M, 2] x, y of the platen's sphere centres: a square grid of spacing ``wall_spacing`` wall radii
    whose outer spheres keep PLATEN_CLEARANCE wall radii from the box's inner faces (it never touches the
    side walls)."""
    length, width, _ = cfg["box"]
    rw = cfg["wall_radius"]
    edge = (1.0 + PLATEN_CLEARANCE) * rw
    step = cfg["wall_spacing"] * rw
    xs, ys = _grid(edge, length - edge, step), _grid(edge, width - edge, step)
    return np.stack(np.meshgrid(xs, ys, indexing="ij"), -1).reshape(-1, 2)


def platen_particles(cfg: dict, soil: dem.Particles) -> dem.Particles:
    """The platen resting on the settled soil: its grid (:func:`platen_grid`) at the lowest height where
    no platen sphere overlaps a soil sphere (it touches the highest point of the surface)."""
    rw = cfg["wall_radius"]
    xy = platen_grid(cfg)
    reach = soil.radius[None, :] + rw
    d2 = ((xy[:, None, :] - soil.x[None, :, :2]) ** 2).sum(-1)
    lift = np.where(d2 < reach**2, soil.x[None, :, 2] + np.sqrt(np.maximum(reach**2 - d2, 0.0)), -np.inf)
    z = max(float(lift.max()), float((soil.x[:, 2] + soil.radius).max()) - rw) if len(soil.x) else rw
    xyz = np.column_stack([xy, np.full(len(xy), z)])
    return dem.Particles(xyz, np.full(len(xy), rw), np.full(len(xy), PLATEN))


def platen_force(row: dict) -> float:
    """The platen's external force along z (N): the normal load less the platen's weight, downwards, so that
    weight plus force press on the soil with exactly normal_stress x L x W."""
    length, width, _ = row["box"]
    return -(row["normal_stress"] * length * width - row["platen_mass"] * row["gravity"])


def flanges(cfg: dict) -> dem.Particles:
    """The box's two flanges at the split plane, as deep as the sweep's largest displacement (``domain_displacement``):
    they stand for the thickness of a laboratory box's walls, which the wall spheres (one layer) lack. Without them
    the shear opens a gap as wide as the displacement at the trailing edge, through which the upper half's soil
    falls out of the box once it is wider than a sphere (12 mm of quasi-static shear lost a sphere so):

    - trailing flange (lower half, moves with it): a plate of wall spheres just below the split plane (centres at
      z_s - r_w) outside the box's x = 0 face, from the face back by the displacement; as the lower half moves
      it slides under the upper half's soil at the trailing edge and carries it, as a thick wall's top would;
    - leading flange (upper half, held): a plate just above the split plane (centres at z_s + r_w) outside the
      x = L face, out by the displacement: a lid over the lower half's soil that the shear carries past x = L.

    Both span the box's width and its side walls, on the walls' square grid."""
    length, width, _ = cfg["box"]
    rw, reach = cfg["wall_radius"], float(cfg["domain_displacement"])
    step = cfg["wall_spacing"] * rw
    ys = _grid(-rw, width + rw, step)
    trailing = _grid(-rw - reach, -rw, step)[:-1]
    leading = _grid(length + rw, length + rw + reach, step)[1:]
    zs = split_height(cfg)
    xyz = np.concatenate([np.stack(np.meshgrid(trailing, ys, [zs - rw], indexing="ij"), -1).reshape(-1, 3),
                          np.stack(np.meshgrid(leading, ys, [zs + rw], indexing="ij"), -1).reshape(-1, 3)])
    lower = np.arange(len(xyz)) < len(trailing) * len(ys)
    return dem.Particles(xyz, np.full(len(xyz), rw), np.full(len(xyz), BOX), {LOWER: lower})


def loaded(packing: dem.Particles, row: dict) -> dem.Particles:
    """The settled packing with its flanges (:func:`flanges`) and the platen on it, and the groups of a sim: the
    lower half (moved), the upper half (its force is the shear force) and the platen."""
    soil = packing.subset(packing.species == SOIL)
    platen = platen_particles(row, soil)
    full = packing.concat(flanges(row)).concat(platen)
    box = full.species == BOX
    groups = {LOWER: full.groups[LOWER] & box, UPPER: box & ~full.groups[LOWER], PLATEN_GROUP: full.species == PLATEN}
    return dem.Particles(full.x, full.radius, full.species, groups)


def observables(row: dict, position: np.ndarray, group_force: dict[str, np.ndarray],
                groups: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The per-frame observables of a sim (module docstring) from its positions [T, N, 3], the contact
    force [T, 3] on the upper half and on the platen, and the particle groups. The shear force is the x
    contact force on the upper half plus that on the platen (both held in x)."""
    length, width, _ = row["box"]
    area = length * width
    position = np.asarray(position, np.float64)
    shear_force = np.asarray(group_force[UPPER], float)[:, 0] + np.asarray(group_force[PLATEN_GROUP], float)[:, 0]
    lower_x = position[:, groups[LOWER], 0].mean(axis=1)
    platen_z = position[:, groups[PLATEN_GROUP], 2].mean(axis=1)
    return {"shear_force": shear_force, "shear_stress": shear_force / area,
            "shear_displacement": lower_x - lower_x[0],
            "normal_stress": np.asarray(group_force[PLATEN_GROUP], float)[:, 2] / area,
            "normal_displacement": platen_z - platen_z[0]}


def peak_shear_stress(shear_stress, smooth: int = 1) -> float:
    """The DEM's peak shear stress (Pa) of a sim: the largest value of its per-frame ``shear_stress``
    observable, after a centred running mean over ``smooth`` frames (1: none); NaN if none is finite."""
    tau = np.asarray(shear_stress, float)
    if smooth > 1 and len(tau) >= smooth:
        tau = np.convolve(tau, np.ones(smooth) / smooth, mode="valid")
    return float(np.nanmax(tau)) if np.isfinite(tau).any() else float("nan")


def domain(cfg: dict, displacement: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounds every particle must stay within: the box walls, shifted by the shear, plus a margin of two wall
    diameters, and up to two box heights; a sim's (a row with ``domain_displacement``) reach back by its trailing
    flange (:func:`flanges`) too."""
    length, width, height = cfg["box"]
    margin = 4.0 * cfg["wall_radius"]
    reach = float(cfg.get("domain_displacement", 0.0))
    return (np.array([-margin - reach, -margin, -margin]),
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
    # DEM-only: from the sim's observables, not from positions, so the surrogate does not predict them (yet)
    dem_names = ("Peak shear stress", "Peak stress ratio")
    units = {"Mean x": "m", **{name: "m" for name in pair_names}, "Peak shear stress": "Pa", "Peak stress ratio": ""}

    @classmethod
    def dem_values(cls, traj) -> dict[str, float]:
        """The DEM's peak shear stress (:func:`peak_shear_stress`) of a sim and its ratio to the set normal
        stress; NaN where the file has no shear_stress observable (written before the load platen)."""
        if "shear_stress" not in traj.observables:
            return {name: float("nan") for name in cls.dem_names}
        peak = peak_shear_stress(traj.observables["shear_stress"])
        stress = float(traj.parameters.get("normal_stress", float("nan")))
        return {"Peak shear stress": peak, "Peak stress ratio": peak / stress}

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


def check_quasi_static(cfg: dict) -> None:
    """Refuse an explicit ``shear_speed`` whose inertial number exceeds ``max_inertial_number`` at the sweep's
    smallest normal stress (where it is largest), naming both keys and the fastest speed allowed."""
    if cfg["shear_speed"] is None:
        return
    stress = min(normal_stress_values(cfg))
    value = inertial_number(cfg, cfg["shear_speed"], stress)
    if value > cfg["max_inertial_number"]:
        allowed = dict(cfg, shear_speed=None)
        raise ConfigError(f"config key 'shear.shear_speed' = {cfg['shear_speed']} m/s shears at the inertial number "
                          f"I = {value:.3g} under the smallest swept normal stress ({stress:g} Pa), above "
                          f"'shear.max_inertial_number' = {cfg['max_inertial_number']} (quasi-static: I at most "
                          f"that): set shear_speed at most {target_speed(allowed, stress):.3g} m/s, or null (derived "
                          "per sim from its normal stress), or raise max_inertial_number")


class Shear(Scene):
    name = "shear"
    dim = 3
    species = {BOX: "box", SOIL: "soil", PLATEN: "platen"}
    kinematic_species = (BOX, PLATEN)
    metrics = ShearMetrics
    log_scaled_properties = ("young", "normal_stress")
    observable_units = OBSERVABLES

    def packings(self, cfg: dict) -> list[dict]:
        """The one packing every sim shares: settled with the stiffest swept modulus.

        Under self-weight the overlaps are below 1e-4 radii at every modulus of the sweep, so the
        geometry barely depends on it; settling at the stiffest keeps overlaps smallest, and a softer
        sim starts by sagging a few micrometres (never by springing apart).
        """
        return [self.packing_params(cfg, young=float(max(young_values(cfg))))]

    def _axes(self, cfg: dict) -> list[tuple[float, float, float]]:
        return [(e, s, float(d)) for e in young_values(cfg) for s in normal_stress_values(cfg)
                for d in cfg["sweep"]["displacements"]]

    def sweep_size(self, cfg: dict) -> int:
        return len(young_values(cfg)) * len(normal_stress_values(cfg)) * len(cfg["sweep"]["displacements"])

    def draw(self, cfg: dict, index: int, rng: np.random.Generator, packings: list[str]) -> dict:
        """The soil modulus x normal stress x shear displacement grid, modulus varying slowest; one shared
        packing."""
        young, stress, displacement = self._axes(cfg)[index]
        return {"young": young, "normal_stress": stress, "displacement": displacement, "packing": packings[0]}

    def finish_sweep(self, rows: list[dict], cfg: dict) -> None:
        """``domain_displacement``, the largest displacement, fixes the same data bounds for every sim."""
        for row in rows:
            row["domain_displacement"] = max(float(d) for d in cfg["sweep"]["displacements"])

    def settle_setup(self, params: dict) -> dem.Setup:
        """The loose soil poured into the box (walls extended upwards)."""
        name = f"packing E = {params['young']:g} Pa"
        return self.setup(params, name, loose_packing(params), dem_step(params, name), domain(params, 0.0),
                          self.settling(params, "viscous"))

    def settled(self, params: dict, particles: dem.Particles, where: str) -> dem.Particles:
        """The settled pour, refused if under-filled, trimmed at the box height."""
        check_filled(particles, params, where)
        return trim(particles, params)

    def simulate_setup(self, row: dict, packing: dem.Particles) -> dem.Setup:
        """The platen placed on the soil (:func:`loaded`) loads it for ``load_time`` (its external force
        ramping up over the first half), the box still; then the lower box moves along +x at a speed that
        gives exactly ``displacement`` at the last frame (:func:`frame_steps`: at most ``max_inertial_number``),
        frame 0 at the start of the shear."""
        step = dem_step(row, where=row["id"])
        dt = step[0]
        every = frame_steps(row, dt)
        start = every * int(math.ceil(row["load_time"] / (every * dt)))     # recording starts on a frame step
        speed = frame_speed(row, every, dt)
        box_lower, box_upper = domain(row, row["domain_displacement"])
        platen = dem.Platen(PLATEN_GROUP, float(row["platen_mass"]), platen_force(row), axis=2,
                            ramp=max(1, start // 2))
        return self.setup(row, row["id"], loaded(packing, row), step, domain(row, row["displacement"]),
                          lambda dt: dem.RecordingSchedule(start=start, every=every, frames=row["frames"]),
                          motions=(dem.Motion(LOWER, (speed, 0.0, 0.0), from_record=True),), platen=platen,
                          force_groups=(UPPER, PLATEN_GROUP), force_samples=FORCE_SAMPLES, box_lower=box_lower,
                          box_upper=box_upper)

    def physics(self, trajectories: list, out_csv, out_png, cfg: dict):
        """The strength of the DEM data: peak and residual shear stress, dilation and inertial number per sim, and
        the Mohr-Coulomb envelopes over the swept normal stresses (generators/scenes/shear_strength.py)."""
        from generators.scenes import shear_strength
        return shear_strength.physics(trajectories, out_csv, out_png)

    def motion_interval(self, cfg: dict) -> float:
        """The longest frame interval: the largest swept displacement at the slowest shear, over the frames."""
        return max(float(d) for d in cfg["sweep"]["displacements"]) / slowest_speed(cfg) / (cfg["frames"] - 1)

    def h5md_parameters(self, row: dict, setup: dem.Setup) -> dict:
        speed = setup.motions[0].velocity[0]
        return {"split_height": split_height(row), "shear_speed": speed, "shear_rate": speed / float(row["box"][2]),
                "inertial_number": inertial_number(row, speed, row["normal_stress"]),
                "platen_force": setup.platen.force,
                "load_steps": setup.schedule.start, "shear_area": float(row["box"][0] * row["box"][1])}

    def observables(self, row: dict, setup: dem.Setup, frames: dem.Frames) -> dict[str, np.ndarray]:
        return observables(row, frames.position, frames.group_force, setup.particles.groups)

    def properties(self, row: dict) -> dict[str, float]:
        return {"young": row["young"], "normal_stress": row["normal_stress"]}

    def particle_estimate(self, cfg: dict) -> int:
        """Lattice sites of the loose pour (FILL_FACTOR box heights) plus the box's and the platen's wall
        spheres."""
        length, width, height = cfg["box"]
        step = cfg["wall_spacing"] * cfg["wall_radius"]
        walls = (2 * length * width + 2 * (length + width) * FILL_FACTOR * height) / step ** 2
        return int(lattice_count(length * width * FILL_FACTOR * height, cfg["radius"][1], 3) + walls)

    def check(self, cfg: dict) -> None:
        check_range(self.name, "sweep.young", cfg["sweep"]["young"])
        check_range(self.name, "sweep.normal_stress", cfg["sweep"]["normal_stress"])
        check_quasi_static(cfg)
        length, width, _ = cfg["box"]
        weight = cfg["platen_mass"] * cfg["gravity"]
        if weight >= min(cfg["sweep"]["normal_stress"]) * length * width:
            raise ConfigError(f"config key 'shear.platen_mass' = {cfg['platen_mass']} kg weighs {weight:.4g} N, more "
                              f"than the smallest normal load ({min(cfg['sweep']['normal_stress'])} Pa x L x W = "
                              f"{min(cfg['sweep']['normal_stress']) * length * width:.4g} N): lighten the platen")
        if cfg["wall_radius"] * (cfg["wall_spacing"] / 2**0.5 - 1.0) >= cfg["radius"][0]:
            raise ConfigError(f"config keys 'shear.wall_radius' = {cfg['wall_radius']} and 'shear.wall_spacing' = "
                              f"{cfg['wall_spacing']} leave holes in the box walls wider than the smallest soil "
                              f"sphere ({cfg['radius'][0]} m): lower the spacing or raise the wall radius")
        if PLATEN_CLEARANCE * cfg["wall_radius"] >= cfg["radius"][0]:
            raise ConfigError(f"config key 'shear.wall_radius' = {cfg['wall_radius']} leaves a gap of "
                              f"{PLATEN_CLEARANCE} wall radii between platen and box walls wider than the smallest "
                              f"soil sphere ({cfg['radius'][0]} m)")


SCENE = Shear()
