"""Meteorite metrics (Table 2) on a hand-built impact with known answers."""

import numpy as np
import pytest

from generators.scenes.meteorite import MeteoriteMetrics

NAN = np.nan


def impact() -> tuple[MeteoriteMetrics, np.ndarray]:
    """Five ground discs (r = 1, d = 2) at y = 0 and one meteorite disc; width 50 m.

    frame 0: meteorite at (25, 10), above everything; frame 1: it touches the ground disc at x = 25
    (x0 = 25); frame 2: that disc is pushed down to y = -4, the one at x = 35 is thrown to (38, 5)."""
    species = np.array([0, 0, 0, 0, 0, 1])
    radius = np.ones(6)
    ground = np.array([[5, 0], [15, 0], [25, 0], [35, 0], [45, 0]], float)
    f0 = np.vstack([ground, [25, 10]])
    f1 = np.vstack([ground, [25, 1.5]])
    f2 = f1.copy()
    f2[2] = [25, -4]
    f2[3] = [38, 5]
    f2[5] = [24, -1]
    return MeteoriteMetrics(species, radius, np.ones(6), 50.0), np.stack([f0, f1, f2])


def test_ground_level_and_impact_point():
    metrics, pos = impact()
    assert metrics.threshold == 2.0
    assert metrics.ground_level(pos) == 0.0
    assert metrics.impact_x(pos) == 25.0
    assert np.isnan(metrics.impact_x(pos[:1]))          # no contact in frame 0 alone


def test_crater_and_splash_values():
    metrics, pos = impact()
    m = metrics(pos)
    np.testing.assert_array_equal(m["Imp Dep"], [NAN, NAN, 4.0])       # nothing disturbed before frame 2
    np.testing.assert_array_equal(m["Cra Dep"], [NAN, NAN, 4.0])       # lowest profile bin in [25, 38]: y = -4
    np.testing.assert_array_equal(m["Imp R(L)"], [NAN, NAN, 0.0])      # disturbed at x = 25 = x0 and 38
    np.testing.assert_array_equal(m["Imp R(R)"], [NAN, NAN, 13.0])
    np.testing.assert_array_equal(m["Sp Num(L)"], [0, 0, 0])
    np.testing.assert_array_equal(m["Sp Num(R)"], [1, 0, 1])          # the meteorite itself, then the thrown disc
    np.testing.assert_array_equal(m["Max Ht(R)"], [10.0, NAN, 5.0])
    np.testing.assert_array_equal(m["Mean Ht(R)"], [10.0, NAN, 5.0])
    assert np.isnan(m["Max Ht(L)"]).all() and np.isnan(m["Mean Ht(L)"]).all()


def test_splash_sides_split_at_the_impact_point():
    metrics, pos = impact()
    pos = pos.copy()
    pos[2, 0] = [3, 7]                     # a second disc thrown up and to the left of x0
    m = metrics(pos)
    assert m["Sp Num(L)"][2] == 1 and m["Max Ht(L)"][2] == 7.0
    assert m["Imp R(L)"][2] == pytest.approx(22.0)


def test_a_side_with_no_disturbed_particle_has_no_reach():
    metrics, pos = impact()
    pos = pos.copy()
    pos[2, 2] = [30, -4]                   # every disturbed disc now lies right of x0 = 25
    m = metrics(pos)
    assert np.isnan(m["Imp R(L)"][2])      # not the negative 25 - 30
    assert m["Imp R(R)"][2] == 13.0


def test_a_non_finite_frame_gives_nan_not_a_number():
    metrics, pos = impact()
    pos = pos.copy()
    pos[2, 3] = np.nan
    m = metrics(pos)
    assert all(np.isnan(v[2]) for v in m.values())
    assert m["Sp Num(R)"][0] == 1


def test_a_domain_that_cannot_hold_the_meteorites_start_is_refused_when_read():
    """The default's start lies at most 110 m high (60 m of bed, a 20 m meteorite's diameter, 10.5 m of flight at
    90 degrees) and 29 m left of the hit point: a 100 m high or 50 m wide domain cannot hold it."""
    from generators import config
    from generators.errors import ConfigError
    for domain in ([500.0, 100.0], [50.0, 300.0], [500.0, 0.0003]):
        with pytest.raises(ConfigError, match=r"'meteorite.domain' = .*'meteorite.bed_depth' = 60.0 m.*at least "
                                              r"58.2 m wide and 110 m high"):
            config.load({"scale": "default", "meteorite": {"domain": domain}})
    assert config.load({"scale": "default", "meteorite": {"domain": [500.0, 120.0]}})["meteorite"]["domain"][1] == 120
