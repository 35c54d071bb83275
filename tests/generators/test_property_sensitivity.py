"""The property-sensitivity test's rerun values (article Fig. 14): points of the swept range, log-interpolated, off
the grid the model trained on, and a config that cannot be tested refused by key before anything runs."""

import numpy as np
import pytest

from generators import config, property_sensitivity
from generators.config import ConfigError
from generators.scenes import shear


def test_the_values_are_the_points_of_the_swept_range_in_log():
    cfg = config.load({"scale": "default"})["shear"]
    lo, hi = cfg["sweep"]["young"]
    low, high = property_sensitivity.values("shear", cfg)
    assert cfg["evaluate"]["property_sensitivity"]["at"] == [0.1, 0.9]
    assert low == pytest.approx(lo * (hi / lo) ** 0.1, rel=1e-5)         # 6 significant figures, as the sweep's
    assert high == pytest.approx(lo * (hi / lo) ** 0.9, rel=1e-5)
    assert np.log(low / lo) == pytest.approx(np.log(hi / high), abs=1e-5)   # symmetric in log about the middle


@pytest.mark.parametrize("scale", ["ci", "default", "paper"])
def test_the_shear_reruns_take_moduli_the_sweep_never_trained_on(scale):
    cfg = config.load({"scale": scale})["shear"]
    grid = shear.young_values(cfg)
    for value in property_sensitivity.values("shear", cfg):
        # off the grid (1.2 % from the nearest of the paper's 20 moduli, 21 % at ci and default scale)
        assert min(abs(value / g - 1.0) for g in grid) > 0.01, (value, grid)
        assert cfg["sweep"]["young"][0] < value < cfg["sweep"]["young"][1]


def test_scenes_without_a_property_sensitivity_have_no_values():
    full = config.load({"scale": "ci"})
    assert [name for name in ("slide", "meteorite", "collapse", "shear")
            if property_sensitivity.values(name, full[name])] == ["shear"]


@pytest.mark.parametrize("override, message", [
    ({"property": "friction", "at": [0.1, 0.9], "tolerance": 0.25}, "property 'friction' is not a node property"),
    ({"property": "young", "at": [0.9, 0.1], "tolerance": 0.25}, "must be two points a < b"),
])
def test_an_untestable_property_sensitivity_is_refused_by_key(override, message):
    with pytest.raises(ConfigError, match=message) as err:
        config.load({"scale": "ci", "shear": {"evaluate": {"property_sensitivity": override}}})
    assert "'shear.evaluate.property_sensitivity'" in str(err.value)


def test_a_property_of_the_model_that_is_not_swept_is_refused():
    cfg = config.load({"scale": "ci"})["shear"]
    cfg = {**cfg, "model": {**cfg["model"], "properties": ["young", "radius"]},
           "evaluate": {**cfg["evaluate"],
                        "property_sensitivity": {"property": "radius", "at": [0.1, 0.9], "tolerance": 0.2}}}
    with pytest.raises(ConfigError, match=r"no swept range 'shear.sweep.radius'"):
        property_sensitivity.values("shear", cfg)


def test_a_point_outside_the_range_is_refused_by_the_schema():
    with pytest.raises(ConfigError, match="property_sensitivity"):
        config.load({"scale": "ci", "shear": {"evaluate": {"property_sensitivity": {
            "property": "young", "at": [0.1, 1.5], "tolerance": 0.25}}}})
