"""Constant-velocity extrapolation: the reference a learned simulator must beat."""

from __future__ import annotations

import numpy as np


def constant_velocity(position: np.ndarray, kinematic: np.ndarray, history: int) -> np.ndarray:
    """Frames ``K..T-1`` extrapolated from the last two history frames, ``p^{t+1} = 2 p^t - p^{t-1}``
    (zero acceleration in eq. 1); kinematic particles follow the data, as in a learned rollout."""
    truth = np.asarray(position, np.float64)
    if history < 2:
        raise ValueError(f"a constant-velocity rollout needs a history of at least 2 frames, got {history}")
    pred = truth.copy()
    kin = np.asarray(kinematic, bool)
    velocity = truth[history - 1] - truth[history - 2]
    for t in range(history, len(truth)):
        pred[t] = pred[t - 1] + velocity
        pred[t, kin] = truth[t, kin]
    return pred
