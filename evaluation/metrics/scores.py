r"""Datum-free errors, skill and the article's Acc of one metric over a test set, with bootstrap intervals.

A metric's values over the test set are held as :class:`Curves`: per sim ``s`` and predicted frame ``tau``
the truth ``M_true(s, tau)``, each member ``j`` of the prediction ``M_pred(s, j, tau)`` (one member for a
model or constant velocity, M for the DEM ensemble's reruns) and the truth at the last given frame
``M_true(s, K-1)``.

* **Change error** (datum-free): the error of the metric's change since the last given frame,
  ``|(M_pred(tau) - M(K-1)) - (M_true(tau) - M(K-1))|``. Prediction and truth share the given frames, so
  this is ``|M_pred(tau) - M_true(tau)|``: a height error does not depend on where zero height is. It is
  averaged over the (member, tau) pairs where both are defined, then over sims (each sim weighs the same).
  Scaled by a physical length for lengths (the mean particle diameter) and, for any other unit (counts,
  energies), by the truth's own mean change ``|M_true(tau) - M_true(K-1)|``.
* **Skill** against a reference (constant velocity): ``1 - err(method) / err(reference)``, the errors paired
  on the same sims (1: perfect, 0: no better than the reference, negative: worse).
* **Undefined values**, symmetrically: a pair where both are undefined (no landslide body in either) is
  skipped; a pair where only one is undefined is counted (``n_undefined_prediction``,
  ``n_undefined_truth``) and its sims named, never scored 0 % or dropped silently.
* **Intervals**: a percentile bootstrap over sims (sims drawn with replacement, every figure recomputed on
  each draw; paired figures such as skill resample the same sims for both methods).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Curves:
    """One metric of one method over a test set (module docstring)."""

    sims: tuple[str, ...]            # [S]
    taus: np.ndarray                 # [T]
    truth: np.ndarray                # [S, T]
    prediction: np.ndarray           # [S, M, T]
    start: np.ndarray                # [S] the truth at the last given frame (NaN where unknown)

    @property
    def both(self) -> np.ndarray:
        """[S, M, T] pairs where truth and prediction are both defined."""
        return np.isfinite(self.prediction) & np.isfinite(self.truth)[:, None, :]


@dataclass(frozen=True)
class Intervals:
    """Bootstrap settings: ``samples`` draws of the sims, central ``level`` interval, seeded by ``seed``."""

    samples: int
    level: float
    seed: int

    def __post_init__(self):
        if isinstance(self.samples, bool) or not isinstance(self.samples, int) or self.samples < 1:
            raise ValueError(f"intervals.samples = {self.samples!r}: a positive integer (bootstrap draws)")
        if not isinstance(self.level, int | float) or not 0.0 < float(self.level) < 1.0:
            raise ValueError(f"intervals.level = {self.level!r}: a number between 0 and 1 (e.g. 0.95)")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"intervals.seed = {self.seed!r}: a non-negative integer")

    def draws(self, n_sims: int) -> np.ndarray:
        """[samples, n_sims] sim indices, drawn with replacement (the same for every figure of a table)."""
        rng = np.random.default_rng(self.seed)
        return rng.integers(0, n_sims, size=(int(self.samples), n_sims))

    def interval(self, values: np.ndarray) -> tuple[float, float]:
        """The central ``level`` interval of bootstrap ``values`` (NaN draws ignored; NaN if all are)."""
        values = np.asarray(values, np.float64)
        values = values[np.isfinite(values)]
        if not values.size:
            return float("nan"), float("nan")
        tail = 50.0 * (1.0 - self.level)
        low, high = np.percentile(values, [tail, 100.0 - tail])
        return float(low), float(high)


def per_sim_change_error(c: Curves) -> np.ndarray:
    """[S] mean |M_pred - M_true| over each sim's (member, tau) pairs where both are defined (NaN: none)."""
    both = c.both
    err = np.where(both, np.abs(c.prediction - c.truth[:, None, :]), 0.0)
    count = both.sum(axis=(1, 2))
    with np.errstate(invalid="ignore"):
        return np.where(count > 0, err.sum(axis=(1, 2)) / np.maximum(count, 1), np.nan)


def per_sim_truth_change(c: Curves) -> np.ndarray:
    """[S] mean |M_true(tau) - M_true(K-1)| over each sim's defined taus (NaN: none, or no start value)."""
    change = np.abs(c.truth - c.start[:, None])
    defined = np.isfinite(change)
    with np.errstate(invalid="ignore"):
        return np.where(defined.any(axis=1), np.where(defined, change, 0.0).sum(axis=1)
                        / np.maximum(defined.sum(axis=1), 1), np.nan)


def undefined(c: Curves) -> tuple[int, int, list[str]]:
    """Pairs with only the prediction undefined, pairs with only the truth undefined, and their sims."""
    pred_ok, truth_ok = np.isfinite(c.prediction), np.isfinite(c.truth)[:, None, :]
    only_truth = truth_ok & ~pred_ok
    only_pred = pred_ok & ~truth_ok
    sims = [s for s, a, b in zip(c.sims, only_truth.any(axis=(1, 2)), only_pred.any(axis=(1, 2)), strict=True)
            if a or b]
    return int(only_truth.sum()), int(only_pred.sum()), sims


def curve_acc(c: Curves, frames: list[int] | None, draws: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
    r"""Article-style Acc (%) of the test-set mean curve once per row of ``draws`` ([B, S] sim indices; None: the
    sims as they are, B = 1), and [B, T] the taus it averaged over:

    .. math:: \mathrm{Acc} = \frac{1}{|T|}\sum_{\tau\in T}\Big(1 - \frac{|\bar M_{pred}(\tau) - \bar M_{true}(\tau)|}
              {|\bar M_{true}(\tau)|}\Big) \times 100\,\%

    At each tau both means average over the same pairs, those where both are defined (members first averaged
    within their sim); taus whose mean truth is 0 or undefined, and taus outside ``frames``, are left out."""
    keep = np.ones(len(c.taus), bool) if frames is None else np.isin(c.taus, list(frames))
    both = c.both
    with np.errstate(invalid="ignore"):
        pred = np.where(both, c.prediction, 0.0).sum(axis=1) / np.maximum(both.sum(axis=1), 1)   # [S, T]
    used = both.any(axis=1) & keep[None, :]
    draws = np.arange(len(c.sims))[None, :] if draws is None else draws
    w = used[draws]                                                          # [B, S, T]
    n = w.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        truth_mean = np.where(w, c.truth[draws], 0.0).sum(axis=1) / n
        pred_mean = np.where(w, pred[draws], 0.0).sum(axis=1) / n
        terms = 1.0 - np.abs(pred_mean - truth_mean) / np.abs(truth_mean)
    scored = (n > 0) & np.isfinite(truth_mean) & (truth_mean != 0)
    with np.errstate(invalid="ignore"):
        acc = np.where(scored.any(axis=1), np.where(scored, terms, 0.0).sum(axis=1)
                       / np.maximum(scored.sum(axis=1), 1) * 100.0, np.nan)
    return acc, scored


def mean_and_interval(per_sim: np.ndarray, draws: np.ndarray, intervals: Intervals) -> tuple[float, float, float]:
    """The mean over sims of ``per_sim`` [S] (NaN if any sim is NaN: a blown-up rollout is not averaged away)
    and its bootstrap interval."""
    per_sim = np.asarray(per_sim, np.float64)
    if not np.isfinite(per_sim).all():
        return float("nan"), float("nan"), float("nan")
    return (float(per_sim.mean()), *intervals.interval(per_sim[draws].mean(axis=1)))


def skill_and_interval(errors: np.ndarray, reference: np.ndarray, draws: np.ndarray,
                       intervals: Intervals) -> tuple[float, float, float]:
    """``1 - mean(errors) / mean(reference)`` over sims ([S] each, paired) and its paired bootstrap interval."""
    errors, reference = np.asarray(errors, np.float64), np.asarray(reference, np.float64)
    if not (np.isfinite(errors).all() and np.isfinite(reference).all()) or reference.mean() <= 0:
        return float("nan"), float("nan"), float("nan")
    with np.errstate(invalid="ignore", divide="ignore"):
        boot = 1.0 - errors[draws].mean(axis=1) / reference[draws].mean(axis=1)
    return float(1.0 - errors.mean() / reference.mean()), *intervals.interval(boot)
