"""Evaluation metrics (docs/surrogate.md): one function per scene, applied alike to truth and prediction."""

from surrogate.metrics.accuracy import accuracy
from surrogate.metrics.slide import SlideMetrics

# scene name (the H5MD ``parameters/scene`` attribute) -> metric computer
SCENES = {"slide": SlideMetrics}

__all__ = ["SCENES", "SlideMetrics", "accuracy"]
