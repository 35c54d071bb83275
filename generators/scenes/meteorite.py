"""The 2D meteorite impact scene (article 5.1 "Meteorite Impact"): definition, DEM description and
metrics (Table 2).

A granular ground bed, settled once under gravity between fixed side and bottom walls (the
prepare stage), is struck by a meteorite: a disc-shaped cluster of touching particles, so that
it breaks into debris on impact. Species ids: 0 ground, 1 meteorite. No particle is kinematic:
the walls are planar walls and enter the surrogate through its boundary features.

The meteorite flies in the x-y plane at ``angle`` degrees below the horizontal (90: straight
down), moving towards +x, and its path is aimed so that it first touches the bed surface at
``contact_frame`` frames after frame 0 above the middle of the domain.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from generators import contact, dem
from generators.errors import ConfigError
from generators.scene import Scene, check_range, lattice_count, lattice_spacing

GROUND, METEORITE = 0, 1


def loose_bed(cfg: dict, seed) -> dem.Particles:
    """Ground discs on a jittered triangular lattice filling the domain's width up to 1.3 bed depths.

    The lattice spacing is one maximum diameter, so nothing overlaps; settling compacts the bed to
    about ``bed_depth``.
    """
    rng = np.random.default_rng(seed)
    r_min, r_max = cfg["radius"]
    width, _ = cfg["domain"]
    spacing = lattice_spacing(r_max)
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
    return dem.Particles(xy, radius, np.full(len(xy), GROUND))


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


def surface_height(bed: dem.Particles, x: float, half_width: float) -> float:
    """Top of the bed (max y + r of ground particles) within ``half_width`` of ``x``."""
    near = np.abs(bed.x[:, 0] - x) <= half_width
    if not near.any():
        raise ValueError(f"no ground particle within {half_width} m of x = {x} m")
    return float(np.max(bed.x[near, 1] + bed.radius[near]))


def place_meteorite(row: dict, bed: dem.Particles) -> tuple[dem.Particles, np.ndarray]:
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
    return (dem.Particles(np.concatenate([bed.x, xy]), np.concatenate([bed.radius, np.full(len(xy), r)]),
                          np.concatenate([bed.species, np.full(len(xy), METEORITE)])), velocity)


@dataclass
class MeteoriteMetrics:
    """Crater and splash metrics of one trajectory, computed alike for truth and prediction.

    d is one mean ground-particle diameter (or ``disturbance``). Ground level y_g: the mean over
    x-bins of width d of the highest ground-particle centre in the bin, at frame 0. Impact x0: the
    x of the meteorite's centre of mass at the first frame where a meteorite particle touches a
    ground particle. Disturbed: ground particles farther than d from their frame-0 position.
    Splashed: any particle more than d above y_g (before contact that is the meteorite itself).
    """

    species: np.ndarray          # [N] int: 0 ground, 1 meteorite
    radius: np.ndarray           # [N] m
    mass: np.ndarray             # [N] kg
    width: float                 # m, domain width (the x-bins span [0, width])
    disturbance: float | None = None

    names = ("Imp Dep", "Cra Dep", "Imp R(L)", "Imp R(R)", "Sp Num(L)", "Sp Num(R)",
             "Max Ht(L)", "Max Ht(R)", "Mean Ht(L)", "Mean Ht(R)")
    pair_names = ()
    units = {"Imp Dep": "m", "Cra Dep": "m", "Imp R(L)": "m", "Imp R(R)": "m", "Sp Num(L)": "particles",
             "Sp Num(R)": "particles", "Max Ht(L)": "m", "Max Ht(R)": "m", "Mean Ht(L)": "m", "Mean Ht(R)": "m"}

    @classmethod
    def for_trajectory(cls, traj, body_displacement: float | None = None) -> MeteoriteMetrics:
        return cls(np.asarray(traj.species), np.asarray(traj.radius, float), np.asarray(traj.mass, float),
                   float(traj.box_upper[0]), body_displacement)

    @property
    def ground(self) -> np.ndarray:
        return np.asarray(self.species) == GROUND

    @property
    def threshold(self) -> float:
        if self.disturbance is not None:
            return float(self.disturbance)
        return float(2.0 * np.mean(np.asarray(self.radius)[self.ground]))

    def profile(self, position: np.ndarray) -> np.ndarray:
        """[T, B] highest ground-particle centre per x-bin (NaN for an empty bin)."""
        d = self.threshold
        n_bins = int(np.ceil(self.width / d))
        x, y = position[:, self.ground, 0], position[:, self.ground, 1]
        bins = np.clip(np.floor(np.nan_to_num(x, nan=-1.0) / d).astype(int), -1, n_bins)
        out = np.full((len(position), n_bins + 2), -np.inf)
        frames = np.repeat(np.arange(len(position))[:, None], x.shape[1], axis=1)
        np.maximum.at(out, (frames, bins + 1), np.nan_to_num(y, nan=-np.inf))
        out = out[:, 1:-1]
        out[~np.isfinite(out)] = np.nan
        return out

    def ground_level(self, position: np.ndarray) -> float:
        return float(np.nanmean(self.profile(position[:1])))

    def impact_x(self, position: np.ndarray) -> float:
        """x of the meteorite's centre of mass at first contact (NaN if it never touches the ground)."""
        from scipy.spatial import cKDTree  # here, not when the workflow plans (scipy costs ~0.7 s to import)

        met, ground = ~self.ground, self.ground
        r_met, r_ground = self.radius[met], self.radius[ground]
        reach = float(r_met.max() + r_ground.max())
        for frame in position:
            if not np.isfinite(frame).all():
                return float("nan")
            pairs = cKDTree(frame[met]).query_ball_tree(cKDTree(frame[ground]), reach)
            for i, js in enumerate(pairs):
                if js and np.any(np.linalg.norm(frame[ground][js] - frame[met][i], axis=1) < r_met[i] + r_ground[js]):
                    return float(np.average(frame[met, 0], weights=self.mass[met]))
        return float("nan")

    def __call__(self, position: np.ndarray) -> dict[str, np.ndarray]:
        """Per frame: every metric of ``names``; NaN where undefined (no disturbed or splashed
        particle on that side, no contact) and on a non-finite frame."""
        position = np.asarray(position, np.float64)
        d = self.threshold
        y_g = self.ground_level(position)
        x0 = self.impact_x(position)
        x, y = position[..., 0], position[..., 1]
        with np.errstate(invalid="ignore"):
            moved = np.linalg.norm(position - position[0], axis=-1)
            disturbed = (moved > d) & self.ground[None, :]
            splashed = y - y_g > d
        nan = np.full(len(position), np.nan)

        def reduce(mask, values, how):
            with warnings.catch_warnings():          # all-NaN rows (nothing disturbed/splashed) give NaN
                warnings.simplefilter("ignore", RuntimeWarning)
                return how(np.where(mask, values, np.nan), axis=1)

        depth = reduce(disturbed, y_g - y, np.nanmax)
        # reach on each side counts only that side's disturbed particles (one at x0 counts on both with 0);
        # a side with none is NaN, never a negative reach
        with np.errstate(invalid="ignore"):
            left_reach = reduce(disturbed & (x <= x0), x0 - x, np.nanmax)
            right_reach = reduce(disturbed & (x >= x0), x - x0, np.nanmax)
        # crater: lowest point of the surface profile between the outermost disturbed particles
        profile = self.profile(position)
        centres = (np.arange(profile.shape[1]) + 0.5) * d
        lo, hi = reduce(disturbed, x, np.nanmin), reduce(disturbed, x, np.nanmax)
        with np.errstate(invalid="ignore"):
            zone = (centres[None, :] >= lo[:, None] - d / 2) & (centres[None, :] <= hi[:, None] + d / 2)
        crater = y_g - reduce(zone, profile, np.nanmin)
        out = {"Imp Dep": depth, "Cra Dep": crater, "Imp R(L)": left_reach, "Imp R(R)": right_reach}
        height = y - y_g
        for side, mask in (("L", splashed & (x < x0)), ("R", splashed & (x >= x0))):
            count = mask.sum(axis=1).astype(float)
            out[f"Sp Num({side})"] = np.where(np.isfinite(x0), count, nan)
            out[f"Max Ht({side})"] = reduce(mask, height, np.nanmax)
            out[f"Mean Ht({side})"] = reduce(mask, height, np.nanmean)
        broken = ~np.isfinite(position).all(axis=(1, 2))
        for values in out.values():
            values[broken] = np.nan
        return {name: out[name] for name in self.names}

    def compare(self, predicted: np.ndarray, truth: np.ndarray) -> dict[str, np.ndarray]:
        return {}


def _bounds(p: dict) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros(2), np.asarray(p["domain"], float)


def _walls(p: dict) -> tuple[dem.PlanarWall, ...]:
    """Fixed planar walls at both sides and at the bottom of the domain."""
    return dem.PlanarWall(0, 0.0, p["domain"][0]), dem.PlanarWall(1, 0.0, None)


def _grid(lo: float, hi: float, n: int) -> list[float]:
    return [round(float(v), 6) for v in (np.linspace(lo, hi, n) if n > 1 else [0.5 * (lo + hi)])]


class Meteorite(Scene):
    name = "meteorite"
    dim = 2
    species = {GROUND: "ground", METEORITE: "meteorite"}
    kinematic_species = ()
    metrics = MeteoriteMetrics

    def packings(self, cfg: dict) -> list[dict]:
        """One bed, shared by every sim."""
        return [self.packing_params(cfg, 0)]

    def _axes(self, cfg: dict) -> list[tuple[float, float]]:
        sw = cfg["sweep"]
        angles, speeds = _grid(*sw["angle"], sw["n_angles"]), _grid(*sw["speed"], sw["n_speeds"])
        return [(a, s) for a in angles for s in speeds]

    def sweep_size(self, cfg: dict) -> int:
        return cfg["sweep"]["n_angles"] * cfg["sweep"]["n_speeds"]

    def draw(self, cfg: dict, index: int, rng: np.random.Generator, packings: list[str]) -> dict:
        """The impact angle x speed grid (article 5.1: 31 x 31 at paper scale), angle varying slowest."""
        angle, speed = self._axes(cfg)[index]
        return {"angle": angle, "speed": speed, "packing": packings[0]}

    def settle_setup(self, params: dict) -> dem.Setup:
        loose = loose_bed(params, seed=[params["seed"], 2000 + params["packing_index"]])
        return self.setup(params, "meteorite", loose, contact.time_step(params, "meteorite", self.dim), _bounds(params),
                          self.settling(params, "viscous"), walls=_walls(params))

    def simulate_setup(self, row: dict, packing: dem.Particles) -> dem.Setup:
        particles, velocity = place_meteorite(row, packing)
        initial = np.zeros_like(particles.x)
        initial[particles.species == METEORITE] = velocity

        def schedule(dt: float) -> dem.RecordingSchedule:
            every = max(1, int(round(row["frame_interval"] / dt)))
            return dem.RecordingSchedule(start=0, every=every, frames=row["frames"])

        return self.setup(row, row["id"], particles, contact.time_step(row, row["id"], self.dim), _bounds(row),
                          schedule, velocity=initial, max_energy_gain=row["max_energy_gain"], walls=_walls(row))

    def h5md_parameters(self, row: dict, setup: dem.Setup) -> dict:
        launch = setup.velocity[setup.particles.species == METEORITE][0]
        return {"launch_velocity": [float(v) for v in launch]}

    def particle_estimate(self, cfg: dict) -> int:
        """Lattice sites of the loose bed (the domain's width, 1.3 bed depths) plus the meteorite's discs."""
        width, _ = cfg["domain"]
        r_mean = 0.5 * (cfg["radius"][0] + cfg["radius"][1])
        cluster = math.pi * cfg["meteorite_radius"] ** 2 / (2 * math.sqrt(3) * r_mean ** 2)
        return int(lattice_count(width * 1.3 * cfg["bed_depth"], cfg["radius"][1], 2) + cluster)

    def check(self, cfg: dict) -> None:
        for key in ("angle", "speed"):
            check_range(self.name, f"sweep.{key}", cfg["sweep"][key])
        check_flight_room(cfg)
        if cfg["contact_frame"] >= cfg["model"]["history"]:
            raise ConfigError(f"config key 'meteorite.contact_frame' = {cfg['contact_frame']} must be below "
                              f"'meteorite.model.history' = {cfg['model']['history']}: the impact point x0 is taken "
                              "at first contact, which must lie in the history both truth and prediction share")


def check_flight_room(cfg: dict) -> None:
    """Refuse a domain that cannot hold the meteorite's start: above the nominal bed (``bed_depth``) by its radius
    and the flight before contact (``contact_frame`` frames at the fastest swept speed) at the steepest swept angle,
    and to the right of x = 0 by that flight at the flattest; the exact start is checked again per sim."""
    width, height = cfg["domain"]
    flight = cfg["contact_frame"] * cfg["frame_interval"] * max(cfg["sweep"]["speed"])
    top = cfg["bed_depth"] + 2.0 * cfg["meteorite_radius"] + flight * math.sin(math.radians(max(cfg["sweep"]["angle"])))
    left = 0.5 * width - cfg["meteorite_radius"] - flight * math.cos(math.radians(min(cfg["sweep"]["angle"])))
    if top >= height or left <= 0:
        raise ConfigError(f"config key 'meteorite.domain' = {cfg['domain']} cannot hold the meteorite's start: "
                          f"'meteorite.bed_depth' = {cfg['bed_depth']} m, 'meteorite.meteorite_radius' = "
                          f"{cfg['meteorite_radius']} m and {flight:.3g} m of flight before contact "
                          f"('meteorite.contact_frame' = {cfg['contact_frame']}, 'meteorite.frame_interval' = "
                          f"{cfg['frame_interval']}, 'meteorite.sweep.speed' = {cfg['sweep']['speed']}, "
                          f"'meteorite.sweep.angle' = {cfg['sweep']['angle']}) need a domain at least "
                          f"{width - 2 * left:.3g} m wide and {top:.3g} m high")


SCENE = Meteorite()
