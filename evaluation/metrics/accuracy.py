"""Acc(M) of the article (section 5.2), with the truth in the denominator: taken the article's way on the
test-set mean curve (:func:`curve_accuracy`, the headline), and pooled over every (sim, frame) pair
(:func:`accuracy`, a stricter second figure that is not comparable with the article's)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


def accuracy(truth: np.ndarray, prediction: np.ndarray) -> tuple[float, int]:
    r"""Pooled accuracy over (sim, frame) pairs, and the number of pairs left out.

    .. math::
        \mathrm{Acc}(M) = \frac{1}{|F|}\sum_{\tau \in F}\Big(1 - \frac{|M_{pred}(\tau) - M_{true}(\tau)|}
        {|M_{true}(\tau)|}\Big) \times 100\,\%

    F holds the pairs whose truth and prediction are both defined and whose truth is non-zero; every other
    pair is left out and counted: a truth of 0, an undefined value on either side (no landslide body yet, an
    empty predicted body). Undefined values are treated alike on both sides, never scored 0 %
    (:mod:`evaluation.metrics.scores` counts the one-sided ones). Returns ``(nan, n_left_out)`` when every
    pair is left out.
    """
    truth = np.asarray(truth, np.float64).ravel()
    prediction = np.asarray(prediction, np.float64).ravel()
    if truth.shape != prediction.shape:
        raise ValueError(f"truth and prediction differ in length: {truth.shape} vs {prediction.shape}")
    kept = np.isfinite(truth) & (truth != 0) & np.isfinite(prediction)
    left_out = int((~kept).sum())
    if not kept.any():
        return float("nan"), left_out
    t, p = truth[kept], prediction[kept]
    return float((1.0 - np.abs(p - t) / np.abs(t)).mean() * 100.0), left_out


@dataclass(frozen=True)
class CurveAccuracy:
    """Article-style Acc and what it was taken over."""

    acc: float                      # percent; NaN when no frame of the set is scored
    frames: tuple[int, ...]         # the taus averaged over
    left_out: tuple[int, ...]       # taus of the set whose mean truth is 0 or undefined
    missing: tuple[int, ...]        # taus of the set the rollout does not reach
    undefined_prediction: int       # (sim, tau) pairs of scored taus whose prediction is undefined


def curve_accuracy(tau: np.ndarray, truth: np.ndarray, prediction: np.ndarray,
                   frames: Sequence[int] | None = None) -> CurveAccuracy:
    r"""Acc of the test-set mean curve, the article's way (its Tables 2 and 3 follow from their own columns).

    .. math::
        \mathrm{Acc}(M) = \frac{1}{|T|}\sum_{\tau \in T}\Big(1 - \frac{|\bar M_{pred}(\tau) - \bar M_{true}(\tau)|}
        {|\bar M_{true}(\tau)|}\Big) \times 100\,\%

    ``tau``, ``truth`` and ``prediction`` hold one entry per (sim, tau). At each tau, both bar means average
    over the same entries, those where truth and prediction are both defined (an undefined value on either side
    is left out and counted in ``undefined_prediction`` where only the prediction is undefined). T is ``frames``
    (every tau present when None), less the taus whose mean truth is 0 or undefined (left out, listed) and those
    beyond the rollout (missing, listed).
    """
    tau = np.asarray(tau).ravel()
    truth = np.asarray(truth, np.float64).ravel()
    prediction = np.asarray(prediction, np.float64).ravel()
    if not tau.shape == truth.shape == prediction.shape:
        raise ValueError(f"tau, truth and prediction differ in length: {tau.shape}, {truth.shape}, "
                         f"{prediction.shape}")
    present = sorted({int(t) for t in tau})
    wanted = present if frames is None else sorted({int(f) for f in frames})
    missing = tuple(t for t in wanted if t not in present)
    terms, scored, left_out, undefined = [], [], [], 0
    for t in (t for t in wanted if t in present):
        defined = (tau == t) & np.isfinite(truth)
        undefined += int((~np.isfinite(prediction[defined])).sum())
        at = defined & np.isfinite(prediction)
        mean_truth = truth[at].mean() if at.any() else np.nan
        if not np.isfinite(mean_truth) or mean_truth == 0:
            left_out.append(t)
            continue
        scored.append(t)
        terms.append(1.0 - abs(prediction[at].mean() - mean_truth) / abs(mean_truth))
    acc = float(np.mean(terms) * 100.0) if terms else float("nan")
    return CurveAccuracy(acc, tuple(scored), tuple(left_out), missing, undefined)


def frame_list(frames: Sequence[int]) -> str:
    """Taus as text, runs shortened: (1, 2, 3, 4) -> '1-4', (5, 10, 15) -> '5 10 15'."""
    frames = sorted(int(f) for f in frames)
    parts, start = [], None
    for i, f in enumerate(frames):
        start = f if start is None else start
        if i + 1 == len(frames) or frames[i + 1] != f + 1:
            parts.append(str(f) if f == start else f"{start}-{f}" if f > start + 1 else f"{start} {f}")
            start = None
    return " ".join(parts)
