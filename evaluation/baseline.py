"""Constant-velocity extrapolation: the reference a learned simulator must beat.

It is scored with the same runtime switches as the model (:mod:`surrogate.runtime`): where the model's rollout
puts particles back into the box (``keep_in_domain``) or pushes overlaps apart (``contact_correction``), so does
the baseline's, after every extrapolated frame, and its next velocity is the difference of the corrected
positions, as the model's is. It is the model's rollout with zero acceleration in eq. (1). Without a runtime
it is the plain extrapolation ``p^{t+1} = 2 p^t - p^{t-1}``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from generators import h5md
    from surrogate.runtime import Runtime


def constant_velocity(position: np.ndarray, kinematic: np.ndarray, history: int, runtime: Runtime | None = None,
                      box: tuple[np.ndarray, np.ndarray] | None = None,
                      radius: np.ndarray | None = None) -> np.ndarray:
    """Frames ``K..T-1`` extrapolated from the last two history frames at zero acceleration; kinematic particles
    follow the data, as in a learned rollout. With ``runtime``, each frame gets the runtime's corrections (module
    docstring): ``box`` (lower, upper) is the data's box and ``radius`` [N] the particles' radii, needed where the
    runtime clamps to the box or corrects contacts."""
    truth = np.asarray(position, np.float64)
    if history < 2:
        raise ValueError(f"a constant-velocity rollout needs a history of at least 2 frames, got {history}")
    kin = np.asarray(kinematic, bool)
    if runtime is None or not (runtime.keep_in_domain or runtime.contact_correction is not None):
        pred = truth.copy()
        velocity = truth[history - 1] - truth[history - 2]
        for t in range(history, len(truth)):
            pred[t] = pred[t - 1] + velocity
            pred[t, kin] = truth[t, kin]
        return pred
    return _corrected(truth, kin, history, runtime, box, radius)


def _corrected(truth: np.ndarray, kin: np.ndarray, history: int, runtime: Runtime,
               box: tuple[np.ndarray, np.ndarray] | None, radius: np.ndarray | None) -> np.ndarray:
    """The extrapolation with the runtime's corrections after every frame (float64 throughout). The rollout's
    corrections are imported here: scoring stored files alone needs no model code."""
    import torch

    from surrogate.rollout import correct_step, new_counts
    if box is None:
        raise ValueError("a constant-velocity rollout with runtime.keep_in_domain or contact_correction needs the "
                         "data's box")
    if runtime.contact_correction is not None and radius is None:
        raise ValueError("a constant-velocity rollout with runtime.contact_correction needs the particles' radii")
    bounds = SimpleNamespace(lower=torch.as_tensor(np.asarray(box[0], np.float64)),
                             upper=torch.as_tensor(np.asarray(box[1], np.float64)))
    data = torch.as_tensor(truth)
    moving = torch.as_tensor(~kin)
    radii = None if radius is None else torch.as_tensor(np.asarray(radius, np.float64))
    pred = data.clone()
    counts = new_counts()
    for t in range(history, len(truth)):
        frame = torch.where(moving.unsqueeze(-1), 2.0 * pred[t - 1] - pred[t - 2], data[t])
        pred[t] = correct_step(frame, moving, radii, runtime, bounds, counts, pred[t - 1])
    return pred.numpy()


@dataclass(frozen=True)
class Extrapolation:
    """Constant velocity as a model's rollouts ran: under its runtime switches and clamped to its box (the
    checkpoint's data bounds), so that every comparison of a model with constant velocity uses one runtime."""

    runtime: Runtime | None = None
    box: tuple[np.ndarray, np.ndarray] | None = None

    @classmethod
    def of(cls, checkpoint: str | Path, runtime_json: dict | None) -> Extrapolation:
        """The runtime of ``runtime_json`` (the scene's ``runtime`` section; None: no corrections) with the box of
        ``checkpoint``'s model."""
        from surrogate import checkpoint as ckpt
        from surrogate.runtime import Runtime
        if runtime_json is None:
            return cls()
        simulator, _ = ckpt.simulator_from(checkpoint)
        box = (simulator.lower.double().numpy(), simulator.upper.double().numpy())
        return cls(Runtime.from_config(runtime_json), box)

    def __call__(self, traj: h5md.Trajectory, history: int) -> np.ndarray:
        """Frames 0..T-1 of ``traj``: the data up to ``history``, then the extrapolation."""
        return constant_velocity(traj.position, traj.kinematic, history, self.runtime, self.box, traj.radius)
