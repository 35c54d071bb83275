"""The 2D granular column collapse: definition, DEM description, metrics and the runout-law check.

A rectangular column of discs, width L0 (``column_width``) and height H0 = a L0, rests on a rough floor
(a row of fixed discs) against a back wall at x = 0, held by a gate at x = L0 while it settles
(prepare). Removing the gate releases it (simulate): it collapses and spreads along +x until it comes
to rest. Species ids: 0 floor (kinematic), 1 grain. The sweep is a grid of aspect ratios a
(log-spaced in ``sweep.aspect``) x grain frictions (``sweep.friction``); each aspect ratio has its own
settled column, shared by its frictions.

The classic check (Lube et al. 2005, PRE 72 041301; Lajeunesse et al. 2005, Phys. Fluids 17 103302):
the normalised runout (L_inf - L0) / L0 grows linearly with a for small a and as a^(2/3) for large a;
:meth:`Collapse.physics` fits both regimes on the DEM's final frames and plots them beside the
published laws. a is measured on the settled column (frame 0), not taken from the sweep.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from generators import contact, dem
from generators.errors import ConfigError
from generators.scene import Scene, check_range, lattice_count, lattice_spacing, trajectory_parameters

if TYPE_CHECKING:  # pandas is imported where a table is built, not when the workflow plans
    import pandas as pd

FLOOR, GRAIN = 0, 1
FILL = 1.14               # the loose lattice fills this many nominal heights (it compacts by about 12 %)
SPREAD = 5.0              # the domain (closed by an end wall) holds a runout of SPREAD a^(2/3) L0
# Published laws of (L_inf - L0) / L0, quasi-2D channels: (source, linear prefactor and range,
# power-law prefactor, exponent and range). Lube et al. 2005 (their eqs. 3-4); Lajeunesse et al. 2005 as
# quoted by Lagree, Staron & Popinet 2011 (JFM 686, eq. 3.1).
PUBLISHED = (("Lube et al. 2005", 1.2, 1.8, 1.9, 2.0 / 3.0, 2.8),
             ("Lajeunesse et al. 2005", 1.8, 3.0, 2.3, 2.0 / 3.0, 3.0))


def aspects(cfg: dict) -> list[float]:
    lo, hi = cfg["sweep"]["aspect"]
    n = int(cfg["sweep"]["n_aspects"])
    values = np.geomspace(lo, hi, n) if n > 1 else np.array([math.sqrt(lo * hi)])
    return [float(f"{v:.6g}") for v in values]


def floor_top(cfg: dict) -> float:
    return 2.0 * cfg["floor_radius"]


def domain(cfg: dict) -> np.ndarray:
    """Width and height that hold every column of the sweep and its runout."""
    a_max = max(float(a) for a in cfg["sweep"]["aspect"])
    length = cfg["column_width"] * (1.0 + SPREAD * a_max ** (2.0 / 3.0))
    return np.array([length, floor_top(cfg) + 1.5 * FILL * a_max * cfg["column_width"]])


def floor_particles(cfg: dict, length: float) -> dem.Particles:
    """Fixed discs of ``floor_radius`` touching along y = floor_radius: a rough floor."""
    r = cfg["floor_radius"]
    xs = np.arange(r, length, 1.8 * r)
    return dem.Particles(np.stack([xs, np.full_like(xs, r)], axis=1), np.full(len(xs), r), np.full(len(xs), FLOOR))


def loose_column(cfg: dict, aspect: float, seed) -> dem.Particles:
    """Grains on a jittered triangular lattice filling the column (FILL nominal heights) above the floor."""
    rng = np.random.default_rng(seed)
    r_min, r_max = cfg["radius"]
    width, base = cfg["column_width"], floor_top(cfg)
    spacing = lattice_spacing(r_max)
    rows = np.arange(base + r_max, base + FILL * aspect * width, spacing * math.sqrt(3) / 2)
    xy = [(x, y) for row, y in enumerate(rows)
          for x in np.arange(r_max + (row % 2) * spacing / 2, width - r_max + 1e-12, spacing)]
    xy = np.asarray(xy, float).reshape(-1, 2)
    radius = rng.uniform(r_min, r_max, len(xy))
    slack = np.maximum(spacing / 2 - radius, 0.0)
    angle = rng.uniform(0, 2 * math.pi, len(xy))
    xy += (0.9 * slack * rng.uniform(0, 1, len(xy)))[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    return dem.Particles(xy, radius, np.full(len(xy), GRAIN))


@dataclass
class CollapseMetrics:
    """Runout and height of the granular mass per frame, and the deposit profile's deviation.

    Profile: the highest grain top above the floor per x-bin of one mean diameter from the back wall.
    Runout: the front of the continuous mass, the right edge of the last occupied bin before the first
    empty one, minus L0 (m): single grains that rolled away ahead of the mass do not count. Height:
    max(y + r) over grains above the floor's top (m). Profile dev: mean over bins (where either profile
    has a grain) of |h_pred(x) - h_true(x)| (m).
    """

    kinematic: np.ndarray
    radius: np.ndarray
    column_width: float
    floor: float

    names = ("Runout", "Height")
    pair_names = ("Profile dev",)
    units = {"Runout": "m", "Height": "m", "Profile dev": "m"}

    @classmethod
    def for_trajectory(cls, traj, body_displacement: float | None = None) -> CollapseMetrics:
        width, floor_radius = trajectory_parameters(traj, ("column_width", "floor_radius"), "collapse")
        return cls(np.asarray(traj.kinematic, bool), np.asarray(traj.radius, float), width, 2.0 * floor_radius)

    def __call__(self, position: np.ndarray) -> dict[str, np.ndarray]:
        grains = ~self.kinematic
        p = np.asarray(position, np.float64)[:, grains]
        r = self.radius[grains]
        occupied = np.isfinite(self.profile(position))
        gaps = ~occupied
        first_gap = np.where(gaps.any(axis=1), gaps.argmax(axis=1), occupied.shape[1])
        front = first_gap * self.bin_width
        front[~np.isfinite(p).all(axis=(1, 2))] = np.nan
        return {"Runout": front - self.column_width, "Height": (p[..., 1] + r).max(axis=1) - self.floor}

    @property
    def bin_width(self) -> float:
        return 2.0 * float(self.radius[~self.kinematic].mean())

    def profile(self, position: np.ndarray) -> np.ndarray:
        """[T, B] highest grain top per x-bin of one mean diameter from x = 0 (NaN: empty bin)."""
        grains = ~self.kinematic
        p = np.asarray(position, np.float64)[:, grains]
        r = self.radius[grains]
        d = self.bin_width
        finite = np.isfinite(p).all(axis=-1)
        bins = np.where(finite, np.floor(np.nan_to_num(p[..., 0]) / d), -1).astype(int)
        n_bins = int(max(bins.max(), 0)) + 1
        out = np.full((len(p), n_bins + 1), -np.inf)
        frames = np.repeat(np.arange(len(p))[:, None], p.shape[1], axis=1)
        np.maximum.at(out, (frames, np.clip(bins, -1, n_bins - 1) + 1), np.where(finite, p[..., 1] + r, -np.inf))
        out = out[:, 1:] - self.floor
        out[~np.isfinite(out)] = np.nan
        return out

    def compare(self, predicted: np.ndarray, truth: np.ndarray) -> dict[str, np.ndarray]:
        """Per frame: Profile dev (m); +inf where a predicted grain is non-finite (a blow-up)."""
        pred, true = self.profile(predicted), self.profile(truth)
        n = max(pred.shape[1], true.shape[1])
        pred, true = (np.pad(a, ((0, 0), (0, n - a.shape[1])), constant_values=np.nan) for a in (pred, true))
        either = np.isfinite(pred) | np.isfinite(true)
        gap = np.abs(np.nan_to_num(pred, nan=0.0) - np.nan_to_num(true, nan=0.0))
        with np.errstate(invalid="ignore"):
            dev = np.where(either, gap, 0.0).sum(axis=1) / np.maximum(either.sum(axis=1), 1)
        broken = ~np.isfinite(np.asarray(predicted)[:, ~self.kinematic]).all(axis=(1, 2))
        dev[broken] = np.inf
        return {"Profile dev": dev}


class Collapse(Scene):
    name = "collapse"
    dim = 2
    species = {FLOOR: "floor", GRAIN: "grain"}
    kinematic_species = (FLOOR,)
    metrics = CollapseMetrics
    check_keys = ("rest_time",)

    def packings(self, cfg: dict) -> list[dict]:
        """One settled column per aspect ratio, shared by the frictions of the sweep."""
        return [self.packing_params(cfg, aspect=a) for a in aspects(cfg)]

    def _grid(self, cfg: dict) -> list[tuple[int, float]]:
        return [(i, float(mu)) for i in range(len(aspects(cfg))) for mu in cfg["sweep"]["friction"]]

    def sweep_size(self, cfg: dict) -> int:
        return len(self._grid(cfg))

    def draw(self, cfg: dict, index: int, rng: np.random.Generator, packings: list[str]) -> dict:
        """Aspect ratio x grain friction, aspect varying slowest; the column of that aspect ratio."""
        i, friction = self._grid(cfg)[index]
        return {"aspect": aspects(cfg)[i], "friction": friction, "packing": packings[i]}

    def finish_sweep(self, rows: list[dict], cfg: dict) -> None:
        """The domain that holds every column and runout, the same for every sim (the data's bounds)."""
        for row in rows:
            row["domain"] = [float(v) for v in domain(cfg)]

    def settle_setup(self, params: dict) -> dem.Setup:
        """The loose column between the back wall and the gate at x = L0, on the floor."""
        width = params["column_width"]
        height = floor_top(params) + 1.5 * FILL * params["aspect"] * width
        upper = np.array([2.0 * width, height])
        seed = [params["seed"], int(round(1000 * params["aspect"]))]
        particles = floor_particles(params, upper[0]).concat(loose_column(params, params["aspect"], seed))
        name = f"collapse column a = {params['aspect']:g}"
        return self.setup(params, name, particles, contact.time_step(params, name, self.dim), (np.zeros(2), upper),
                          self.settling(params, "viscous"),
                          walls=(dem.PlanarWall(0, 0.0, width),))

    def simulate_setup(self, row: dict, packing: dem.Particles) -> dem.Setup:
        """The gate removed: the column (on a floor extended over the whole domain, closed by an end wall far
        beyond any published runout) collapses."""
        upper = np.asarray(row["domain"], float)
        grains = packing.subset(packing.species == GRAIN)
        particles = floor_particles(row, upper[0]).concat(grains)

        def schedule(dt: float) -> dem.RecordingSchedule:
            every = max(1, int(round(row["frame_interval"] / dt)))
            return dem.RecordingSchedule(start=0, every=every, frames=row["frames"])

        return self.setup(row, row["id"], particles, contact.time_step(row, row["id"], self.dim), (np.zeros(2), upper),
                          schedule, walls=(dem.PlanarWall(0, 0.0, float(upper[0])),),
                          max_energy_gain=row["max_energy_gain"])

    def h5md_parameters(self, row: dict, setup: dem.Setup) -> dict:
        return {"floor_top": floor_top(row)}

    def particle_estimate(self, cfg: dict) -> int:
        """Lattice sites of the tallest column (FILL nominal heights) plus the floor under the domain."""
        width = cfg["column_width"]
        a_max = max(float(a) for a in cfg["sweep"]["aspect"])
        floor = domain(cfg)[0] / (1.8 * cfg["floor_radius"])
        return int(lattice_count(width * FILL * a_max * width, cfg["radius"][1], 2) + floor)

    def check(self, cfg: dict) -> None:
        check_range(self.name, "sweep.aspect", cfg["sweep"]["aspect"])
        a_max = max(cfg["sweep"]["aspect"])
        needed = cfg["rest_time"] * math.sqrt(a_max * cfg["column_width"] / cfg["gravity"])
        window = cfg["frame_interval"] * (cfg["frames"] - 1)
        if window < needed:
            raise ConfigError(f"config keys 'collapse.frames' = {cfg['frames']} and 'collapse.frame_interval' = "
                              f"{cfg['frame_interval']} record {window:.3g} s; the tallest column (a = {a_max:g} of "
                              f"'collapse.sweep.aspect', 'collapse.column_width' = {cfg['column_width']:g}, "
                              f"'collapse.gravity' = {cfg['gravity']:g}) comes to rest after about "
                              f"'collapse.rest_time' = {cfg['rest_time']:g} sqrt(H0/g) = {needed:.3g} s: record longer")

    # ---- the runout law ----------------------------------------------------------------------------

    def physics(self, trajectories: list, out_csv: Path, out_png: Path, cfg: dict) -> pd.DataFrame:
        """Final runout and height of every sim against its settled aspect ratio, whether it is at rest at its last
        frame (:func:`rest`, at ``cfg['settle_speed']``, the speed that also defines a settled column), the fits of
        both regimes over the sims at rest beside the published laws (rows with ``sim = fit``), and a plot."""
        import pandas as pd

        rows = [deposit(traj, float(cfg["settle_speed"])) for traj in trajectories]
        table = pd.DataFrame(rows).sort_values(["friction", "aspect"]).reset_index(drop=True)
        fits = fit_runout(table)
        out = pd.concat([table, fits], ignore_index=True)
        from generators.atomic import atomic_path
        with atomic_path(out_csv) as tmp:
            out.to_csv(tmp, index=False)
        plot_runout(table, fits, [(t, CollapseMetrics.for_trajectory(t)) for t in trajectories], out_png)
        return out


def rest(time: np.ndarray, position: np.ndarray, speed: float) -> tuple[np.ndarray, float]:
    """The grains' RMS speed over each frame interval ([T - 1], from the displacement between frames) and the rest
    time: the start of the last interval from which the RMS speed stays below ``speed`` to the last frame (s;
    NaN where the last interval is not below it: the column is still moving when the record ends)."""
    step = np.diff(np.asarray(position, np.float64), axis=0)
    rms = np.sqrt((step ** 2).sum(axis=-1).mean(axis=-1)) / np.diff(np.asarray(time, np.float64))
    moving = np.flatnonzero(rms >= speed)
    if len(moving) and moving[-1] == len(rms) - 1:
        return rms, float("nan")
    return rms, float(time[moving[-1] + 1] if len(moving) else time[0]) - float(time[0])


def deposit(traj, rest_speed: float) -> dict:
    """One sim's row of the runout table: the column's width in mean grain diameters, settled aspect ratio (frame
    0), final runout and height over L0, the largest grain speed and the RMS speed over the last frame interval,
    at rest or not, and the rest time (s and in units of sqrt(H0 / g) of the settled column)."""
    m = CollapseMetrics.for_trajectory(traj)
    grains = np.asarray(traj.position, np.float64)[:, ~m.kinematic]
    values = m(np.asarray(traj.position, np.float64)[[0, -1]])
    width, height0 = m.column_width, float(values["Height"][0])
    rms, rest_s = rest(np.asarray(traj.time), grains, rest_speed)
    last = np.linalg.norm(grains[-1] - grains[-2], axis=-1).max() / float(traj.time[-1] - traj.time[-2])
    (gravity,) = trajectory_parameters(traj, ("gravity",), "collapse")
    return {"sim": str(traj.parameters.get("id")), "friction": float(traj.parameters["friction"]),
            "column_diameters": width / m.bin_width, "aspect": height0 / width,
            "runout": values["Runout"][1] / width, "height": values["Height"][1] / width,
            "final_max_speed": float(last), "final_rms_speed": float(rms[-1]), "at_rest": bool(np.isfinite(rest_s)),
            "rest_time": rest_s, "rest_time_scaled": rest_s / math.sqrt(height0 / gravity)}


def fit_runout(table: pd.DataFrame) -> pd.DataFrame:
    """Per friction (and all together): the linear prefactor lambda of (L - L0)/L0 = lambda a over the
    sims below Lube's a = 1.8, and c, alpha of c a^alpha (log-log least squares) over those above a = 2.8;
    the final height's exponent above a = 1.15. Only sims at rest (column ``at_rest`` where the table has
    one) are fitted; ``n_moving`` counts those left out. NaN where a regime has too few sims."""
    import pandas as pd

    out = []
    groups = [("all", table)] + [(f"{mu:g}", g) for mu, g in table.groupby("friction")]
    for name, everything in groups:
        g = everything[everything["at_rest"].astype(bool)] if "at_rest" in everything else everything
        small, large, tall = g[g["aspect"] < 1.8], g[g["aspect"] > 2.8], g[g["aspect"] > 1.15]
        lam = float((small["aspect"] * small["runout"]).sum() / (small["aspect"] ** 2).sum()) if len(small) else np.nan
        c = alpha = beta = np.nan
        if len(large) >= 2:
            alpha, logc = np.polyfit(np.log(large["aspect"]), np.log(large["runout"]), 1)
            c = float(np.exp(logc))
        if len(tall) >= 2:
            beta = float(np.polyfit(np.log(tall["aspect"]), np.log(tall["height"]), 1)[0])
        out.append({"sim": "fit", "friction": name, "linear_prefactor": lam, "power_prefactor": c,
                    "power_exponent": float(alpha), "height_exponent": beta,
                    "n_small": len(small), "n_large": len(large), "n_moving": len(everything) - len(g)})
    return pd.DataFrame(out)


def plot_runout(table: pd.DataFrame, fits: pd.DataFrame, deposits: list, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from generators.atomic import atomic_path
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.8), constrained_layout=True)
    a = np.geomspace(0.3, 12, 100)
    for (source, lam, a1, c, alpha, a2), style in zip(PUBLISHED, ("-", "--"), strict=True):
        ax.plot(a[a < a1 * 1.3], lam * a[a < a1 * 1.3], color="black", ls=style, lw=1, label=f"{source}: {lam:g} a")
        ax.plot(a[a > a2 / 1.3], c * a[a > a2 / 1.3] ** alpha, color="grey", ls=style, lw=1,
                label=f"{source}: {c:g} a^(2/3)")
    for mu, g in table.groupby("friction"):
        ax.plot(g["aspect"], g["runout"], "o", label=f"DEM, friction {mu:g}")
        fit = fits[fits["friction"] == f"{mu:g}"].iloc[0]
        if np.isfinite(fit["power_prefactor"]):
            ax.plot(a[a > 2.2], fit["power_prefactor"] * a[a > 2.2] ** fit["power_exponent"], lw=1.5,
                    label=f"fit: {fit['power_prefactor']:.2f} a^{fit['power_exponent']:.2f}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("aspect ratio a = H0 / L0 (settled column)")
    ax.set_ylabel("normalised runout (L_inf - L0) / L0")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    for traj, m in deposits:
        h = m.profile(np.asarray(traj.position, np.float64)[[-1]])[0]
        x = (np.arange(len(h)) + 0.5) * m.bin_width / m.column_width
        bx.plot(x, h / m.column_width, lw=1)
    bx.set_xlabel("x / L0")
    bx.set_ylabel("deposit height / L0 (final frame)")
    bx.grid(alpha=0.3)
    fig.suptitle("granular column collapse: runout against aspect ratio, and the deposits")
    with atomic_path(Path(path)) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


SCENE = Collapse()
