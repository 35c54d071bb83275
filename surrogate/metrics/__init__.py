"""Evaluation metrics (docs/surrogate.md): one class per scene, applied alike to truth and prediction.

Each class has ``for_trajectory(traj, body_displacement)``, ``__call__(position)`` (per-frame
metrics of one trajectory) and ``compare(predicted, truth)`` (per-frame errors of a prediction).
"""

from surrogate.metrics.accuracy import accuracy
from surrogate.metrics.meteorite import MeteoriteMetrics
from surrogate.metrics.shear import ShearMetrics
from surrogate.metrics.slide import SlideMetrics

# scene name (the H5MD ``parameters/scene`` attribute) -> metric computer
SCENES = {"slide": SlideMetrics, "meteorite": MeteoriteMetrics, "shear": ShearMetrics}

__all__ = ["SCENES", "MeteoriteMetrics", "ShearMetrics", "SlideMetrics", "accuracy"]
