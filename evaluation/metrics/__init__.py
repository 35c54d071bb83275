"""Evaluation metrics (docs/surrogate.md): each scene's metric class (its module in generators/scenes),
applied alike to truth and prediction, and the article's Acc.

A metric class has ``for_trajectory(traj, body_displacement)``, ``names``, ``pair_names``, ``units``,
``__call__(position)`` (per-frame metrics of one trajectory) and ``compare(predicted, truth)``
(per-frame errors of a prediction).

Units: each module that names a metric gives its unit beside the name (a scene's metric class ``units``,
:data:`plausibility.UNITS`, :data:`MSE_UNIT` here, the rollout timing's in :mod:`evaluation.evaluate`), as
plain text: SI symbols, ``^2`` for a square, a count's objects (``particles``); metrics.csv's ``unit`` column
holds it as written, :func:`shown` turns it into the form tables and plots print.
"""

from __future__ import annotations

from evaluation.metrics import plausibility
from evaluation.metrics.accuracy import CurveAccuracy, accuracy, curve_accuracy, frame_list
from generators import scenes

MSE, MSE_UNIT = "rollout MSE", "m^2"


def of_scene(name: str):
    """The metric class of scene ``name`` (the H5MD ``parameters/scene`` attribute); None for data of no
    registered scene (e.g. an imported public benchmark, scored by rollout MSE only)."""
    registry = scenes.registry()
    return registry[name].metrics if name in registry else None


def units(scene: str | None = None) -> dict[str, str]:
    """Unit of every metric of ``scene`` (every registered scene's when None), of the plausibility measures and of
    the rollout MSE."""
    out = {MSE: MSE_UNIT, **plausibility.UNITS}
    registry = scenes.registry()
    for name in ([scene] if scene is not None else list(registry)):
        if name in registry:
            out.update(registry[name].metrics.units)
    return out


def shown(unit: str) -> str:
    """A unit as tables and plots print it: ``m^2`` as ``m²``."""
    return str(unit).replace("^2", "²")


__all__ = ["MSE", "MSE_UNIT", "CurveAccuracy", "accuracy", "curve_accuracy", "frame_list", "of_scene",
           "plausibility", "shown", "units"]
