"""Landslide metrics (article Table 3, docs/surrogate.md)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
