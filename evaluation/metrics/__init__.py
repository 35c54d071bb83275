"""Evaluation metrics (docs/surrogate.md): each scene's metric class (its module in generators/scenes),
applied alike to truth and prediction, and the article's Acc.

A metric class has ``for_trajectory(traj, body_displacement)``, ``names``, ``pair_names``, ``units``,
``__call__(position)`` (per-frame metrics of one trajectory) and ``compare(predicted, truth)``
(per-frame errors of a prediction).
"""

from __future__ import annotations

from evaluation.metrics import plausibility
from evaluation.metrics.accuracy import CurveAccuracy, accuracy, curve_accuracy, frame_list
from generators import scenes


def of_scene(name: str):
    """The metric class of scene ``name`` (the H5MD ``parameters/scene`` attribute); None for data of no
    registered scene (e.g. an imported public benchmark, scored by rollout MSE only)."""
    registry = scenes.registry()
    return registry[name].metrics if name in registry else None


def units() -> dict[str, str]:
    """Unit of every metric of every scene, plus the rollout MSE's."""
    out = {"rollout MSE": "m$^2$", **plausibility.UNITS}
    for scene in scenes.registry().values():
        out.update(scene.metrics.units)
    return out


__all__ = ["CurveAccuracy", "accuracy", "curve_accuracy", "frame_list", "of_scene", "plausibility", "units"]
