"""Acc(M) of the article (section 5.2), with the truth in the denominator."""

from __future__ import annotations

import numpy as np


def accuracy(truth: np.ndarray, prediction: np.ndarray) -> tuple[float, int]:
    r"""Pooled accuracy over predicted frames, and the number of frames left out.

    .. math::
        \mathrm{Acc}(M) = \frac{1}{|F|}\sum_{\tau \in F}\Big(1 - \frac{|M_{pred}(\tau) - M_{true}(\tau)|}
        {|M_{true}(\tau)|}\Big) \times 100\,\%

    F holds the frames whose truth is defined and non-zero; frames where the truth is 0 (or
    undefined, e.g. no landslide body yet) are left out and counted. A frame whose prediction is
    undefined while the truth is not (an empty predicted body, a rollout that blew up) scores 0 %.
    Returns ``(nan, n_left_out)`` when every frame is left out.
    """
    truth = np.asarray(truth, np.float64).ravel()
    prediction = np.asarray(prediction, np.float64).ravel()
    if truth.shape != prediction.shape:
        raise ValueError(f"truth and prediction differ in length: {truth.shape} vs {prediction.shape}")
    kept = np.isfinite(truth) & (truth != 0)
    left_out = int((~kept).sum())
    if not kept.any():
        return float("nan"), left_out
    t, p = truth[kept], prediction[kept]
    terms = np.where(np.isfinite(p), 1.0 - np.abs(p - t) / np.abs(t), 0.0)
    return float(terms.mean() * 100.0), left_out
