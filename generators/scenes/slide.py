"""The 2D landslide scene (article 5.1 "Slide"): definition, DEM description and metrics (Table 3).

A bedrock slope of fixed boundary particles carries a soil mass in three layers. A band dipping
downslope (the middle layer) is made of sliding-prone soil: at the trigger its friction drops
and the soil above it slides down the slope. Species ids: 0 bedrock (kinematic), 1 stable soil,
2 sliding-prone soil.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from generators import contact, dem
from generators.scene import Scene, check_range, lattice_count, lattice_spacing

BEDROCK, STABLE, WEAK = 0, 1, 2
WEAK_REFERENCE_X = 40.0   # m, where the weak layer's base height is measured


def polyline_y(points: list[list[float]], x: np.ndarray) -> np.ndarray:
    """Height of a polyline [[x, y], ...] at ``x`` (flat extrapolation beyond its ends)."""
    pts = np.asarray(points, float)
    return np.interp(x, pts[:, 0], pts[:, 1])


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


def loose_packing(cfg: dict, seed) -> dem.Particles:
    """Soil discs on a jittered triangular lattice filling the nominal soil region, plus bedrock.

    The lattice spacing is one maximum diameter, so nothing overlaps; settling under gravity
    (the prepare stage) compacts the mass.
    """
    rng = np.random.default_rng(seed)
    r_min, r_max = cfg["radius"]
    rb = cfg["bedrock_radius"]
    width, _ = cfg["domain"]
    bed_xy, bed_r = bedrock_particles(cfg)
    spacing = lattice_spacing(r_max)
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
    return dem.Particles(np.concatenate([bed_xy, soil_xy]), np.concatenate([bed_r, radius]),
                         np.concatenate([np.full(len(bed_xy), BEDROCK), np.full(len(soil_xy), STABLE)]))


def assign_layers(particles: dem.Particles, weak_base: float, weak_thickness: float,
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


@dataclass
class SlideMetrics:
    """Landslide body metrics of one trajectory.

    The landslide body at frame tau is the set of moving particles displaced by more than
    ``body_displacement`` (m) from their position at frame 0 of the sim; it is determined
    separately in truth and prediction. ``body_displacement`` defaults to one mean diameter of
    the moving particles.
    """

    kinematic: np.ndarray            # [N] bool
    radius: np.ndarray               # [N] m
    body_displacement: float | None = None

    #: per-trajectory metrics (same code for truth and prediction), in output order
    names = ("Slide Num", "Max Ht", "Mean Ht", "Tongue Dis")
    #: metrics comparing a prediction with the truth
    pair_names = ("Dis", "Dis mean")
    units = {"Slide Num": "particles", "Max Ht": "m", "Mean Ht": "m", "Tongue Dis": "m", "Dis": "m", "Dis mean": "m"}

    @classmethod
    def for_trajectory(cls, traj, body_displacement: float | None = None) -> SlideMetrics:
        return cls(np.asarray(traj.kinematic, bool), np.asarray(traj.radius, float), body_displacement)

    @property
    def threshold(self) -> float:
        if self.body_displacement is not None:
            return float(self.body_displacement)
        return float(2.0 * np.mean(np.asarray(self.radius)[~np.asarray(self.kinematic, bool)]))

    def body(self, position: np.ndarray) -> np.ndarray:
        """[T, N] bool: moving particles farther than the threshold from their frame-0 position.

        A non-finite position (a rollout that blew up) is in no body.
        """
        position = np.asarray(position, np.float64)
        moved = np.linalg.norm(position - position[0], axis=-1)
        with np.errstate(invalid="ignore"):
            return (moved > self.threshold) & ~np.asarray(self.kinematic, bool)[None, :] & np.isfinite(moved)

    def __call__(self, position: np.ndarray) -> dict[str, np.ndarray]:
        """Per frame: Slide Num (count), Max Ht and Mean Ht (highest and mean y of the body, m),
        Tongue Dis (largest x reached by a body particle, m). Heights and tongue are NaN for an
        empty body, and every metric is NaN on a non-finite frame."""
        position = np.asarray(position, np.float64)
        body = self.body(position)
        count = body.sum(axis=1).astype(np.float64)
        y = np.where(body, position[..., 1], np.nan)
        x = np.where(body, position[..., 0], np.nan)
        empty = count == 0
        with np.errstate(invalid="ignore"):
            max_ht = np.where(empty, np.nan, np.nanmax(np.where(body, y, -np.inf), axis=1))
            mean_ht = np.where(empty, np.nan, np.nansum(y, axis=1) / np.maximum(count, 1))
            tongue = np.where(empty, np.nan, np.nanmax(np.where(body, x, -np.inf), axis=1))
        broken = ~np.isfinite(position[:, ~np.asarray(self.kinematic, bool)]).all(axis=(1, 2))
        out = {"Slide Num": count, "Max Ht": max_ht, "Mean Ht": mean_ht, "Tongue Dis": tongue}
        for values in out.values():
            values[broken] = np.nan
        return out

    def compare(self, predicted: np.ndarray, truth: np.ndarray) -> dict[str, np.ndarray]:
        """Per frame: Dis, the sum over the *true* body of |p_pred - p_true| (m), and its mean.

        NaN where the true body is empty (undefined, as the heights), +inf where a moving particle's
        predicted position is non-finite (a blow-up is an infinite error, never a missing one).
        """
        predicted = np.asarray(predicted, np.float64)
        body = self.body(truth)
        dist = np.linalg.norm(predicted - np.asarray(truth, np.float64), axis=-1)
        count = body.sum(axis=1)
        total = np.where(body, dist, 0.0).sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = total / np.maximum(count, 1)
        broken = ~np.isfinite(predicted[:, ~np.asarray(self.kinematic, bool)]).all(axis=(1, 2))
        for values in (total, mean):
            values[count == 0] = np.nan
            values[broken] = np.inf
        return {"Dis": total, "Dis mean": mean}


def _bounds(p: dict) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros(2), np.asarray(p["domain"], float)


class Slide(Scene):
    name = "slide"
    dim = 2
    species = {BEDROCK: "bedrock", STABLE: "stable soil", WEAK: "sliding-prone soil"}
    kinematic_species = (BEDROCK,)
    metrics = SlideMetrics

    def sweep_size(self, cfg: dict) -> int:
        return cfg["n_sims"]

    def draw(self, cfg: dict, index: int, rng: np.random.Generator, packings: list[str]) -> dict:
        """Base height, thickness and dip of the weak layer (uniform), optionally its friction, and one
        of the packings."""
        row = {}
        for name in ("weak_base", "weak_thickness", "weak_dip"):
            lo, hi = cfg["sweep"][name]
            row[name] = round(float(rng.uniform(lo, hi)), 4)
        if cfg["sweep"]["weak_friction"] is not None:
            lo, hi = cfg["sweep"]["weak_friction"]
            row["weak_friction"] = round(float(rng.uniform(lo, hi)), 4)
        row["packing"] = packings[int(rng.integers(cfg["n_packings"]))]
        return row

    def settle_setup(self, params: dict) -> dem.Setup:
        loose = loose_packing(params, seed=[params["seed"], 1000 + params["packing_index"]])
        return self.setup(params, "slide", loose, contact.time_step(params, "slide", self.dim), _bounds(params),
                          self.settling(params, "viscous"))

    def simulate_setup(self, row: dict, packing: dem.Particles) -> dem.Setup:
        """The trigger: the weak layer's species gets its lowered friction; frame 0 is recorded
        ``record_start`` after it (rounded to whole frame intervals)."""
        species = assign_layers(packing, row["weak_base"], row["weak_thickness"], row["weak_dip"])
        particles = dem.Particles(packing.x, packing.radius, species)

        def schedule(dt: float) -> dem.RecordingSchedule:
            every = max(1, int(round(row["frame_interval"] / dt)))
            return dem.RecordingSchedule(start=every * int(round(row["record_start"] / (every * dt))), every=every,
                                         frames=row["frames"])

        step = contact.time_step(row, row["id"], self.dim)
        weak = self.contact(row, step[2], row["weak_friction"], row["weak_rolling_friction"])
        return self.setup(row, row["id"], particles, step, _bounds(row), schedule,
                          max_energy_gain=row["max_energy_gain"], species_contacts={WEAK: weak})

    def particle_estimate(self, cfg: dict) -> int:
        """Lattice sites between the bedrock profile and the soil surface, plus the bedrock chain and walls."""
        width, height = cfg["domain"]
        x = np.linspace(0.0, width, 2001)
        depth = np.clip(polyline_y(cfg["soil_surface"], x) - polyline_y(cfg["bedrock_profile"], x), 0.0, None)
        area = float(np.sum(0.5 * (depth[1:] + depth[:-1]) * np.diff(x)))
        profile = np.asarray(cfg["bedrock_profile"], float)
        chain = float(np.sum(np.hypot(*np.diff(profile, axis=0).T))) + 2.0 * height
        return int(lattice_count(area, cfg["radius"][1], 2) + chain / (1.8 * cfg["bedrock_radius"]))

    def check(self, cfg: dict) -> None:
        for key in ("weak_base", "weak_thickness", "weak_dip", "weak_friction"):
            check_range(self.name, f"sweep.{key}", cfg["sweep"][key])


SCENE = Slide()
