"""Meteorite impact metrics (article Table 2, docs/surrogate.md)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

GROUND, METEORITE = 0, 1


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
