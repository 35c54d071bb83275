"""The metrics of each scene found by the scene's name, and the unit of every metric (evaluation/metrics/
__init__.py)."""

from evaluation import metrics
from evaluation.metrics import plausibility
from generators import scenes
from generators.scenes import collapse


def test_each_scene_s_metric_class_and_none_for_data_of_no_scene():
    assert metrics.of_scene("collapse") is collapse.CollapseMetrics
    for name in scenes.names():
        assert metrics.of_scene(name) is scenes.get(name).metrics
    assert metrics.of_scene("solidgn") is None


def test_every_metric_has_its_unit():
    units = metrics.units()
    assert units["rollout MSE"] == "m^2" and units["Runout"] == "m" and units["Profile dev"] == "m"
    for name in scenes.names():
        for metric, unit in scenes.get(name).metrics.units.items():
            assert units[metric] == unit
            assert metrics.units(name)[metric] == unit
    for metric, unit in plausibility.UNITS.items():
        assert units[metric] == unit


def test_a_scene_s_units_are_its_own_and_print_with_a_superscript():
    slide = metrics.units("slide")
    assert slide["Slide Num"] == "particles" and slide["Kinetic energy"] == "J" and "Runout" not in slide
    assert metrics.units("solidgn") == {"rollout MSE": "m^2", **plausibility.UNITS}   # no registered scene
    assert metrics.shown("m^2") == "m²" and metrics.shown("particles") == "particles"
