"""Direct-shear metrics (article Table 4 and Fig. 14, docs/surrogate.md)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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

    @classmethod
    def for_trajectory(cls, traj, body_displacement: float | None = None) -> ShearMetrics:
        p = traj.parameters
        missing = [k for k in ("split_height", "failure_band") if k not in p]
        if missing:
            raise ValueError(f"shear metrics need the parameters {missing} in the H5MD file's parameters; "
                             "files written by `graphdem convert` for the shear scene carry them")
        return cls(np.asarray(traj.kinematic, bool), np.asarray(traj.position[0, :, 2], float),
                   float(p["split_height"]), float(p["failure_band"]))

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
