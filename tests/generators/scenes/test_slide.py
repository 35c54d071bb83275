"""Landslide metrics on a hand-built trajectory with known answers."""

import numpy as np
import pytest

from generators.scenes.slide import SlideMetrics


def trajectory():
    """4 moving particles of radius 0.5 (threshold: one diameter, 1 m) and one kinematic particle.

    Frame 0: at rest. Frame 1: particle 0 moved 2 m along x, particle 1 moved 0.5 m (not body).
    Frame 2: particles 0, 1 and 2 moved 3 m down-slope and 1 m down; particle 3 never moves.
    """
    p0 = np.array([[10.0, 20.0], [12.0, 18.0], [14.0, 16.0], [16.0, 14.0], [30.0, 5.0]])
    pos = np.repeat(p0[None], 3, axis=0)
    pos[1, 0] += [2.0, 0.0]
    pos[1, 1] += [0.5, 0.0]
    pos[2, :3] += [3.0, -1.0]
    pos[:, 4] = [30.0, 5.0]
    kinematic = np.array([False, False, False, False, True])
    return pos, kinematic, np.full(5, 0.5)


def test_body_metrics_per_frame():
    pos, kin, radius = trajectory()
    m = SlideMetrics(kin, radius)(pos)
    np.testing.assert_array_equal(m["Slide Num"], [0, 1, 3])
    assert np.isnan(m["Max Ht"][0]) and np.isnan(m["Tongue Dis"][0])        # no body yet
    assert m["Max Ht"][1] == 20.0 and m["Mean Ht"][1] == 20.0 and m["Tongue Dis"][1] == 12.0
    assert m["Max Ht"][2] == 19.0 and m["Mean Ht"][2] == pytest.approx(17.0) and m["Tongue Dis"][2] == 17.0


def test_kinematic_particles_are_never_in_the_body():
    pos, kin, radius = trajectory()
    pos[2, 4] += [50.0, 0.0]                                     # a wall particle displaced far away
    assert SlideMetrics(kin, radius)(pos)["Slide Num"][2] == 3


def test_threshold_from_config_overrides_one_diameter():
    pos, kin, radius = trajectory()
    assert SlideMetrics(kin, radius).threshold == 1.0
    m = SlideMetrics(kin, radius, body_displacement=2.5)(pos)
    np.testing.assert_array_equal(m["Slide Num"], [0, 0, 3])


def test_dis_sums_distances_over_the_true_body():
    truth, kin, radius = trajectory()
    pred = truth.copy()
    pred[2, 0] += [3.0, 4.0]          # 5 m off, in the true body
    pred[2, 3] += [6.0, 8.0]          # 10 m off, but not in the true body: not counted
    d = SlideMetrics(kin, radius).compare(pred, truth)
    np.testing.assert_allclose(d["Dis"][1:], [0.0, 5.0])
    assert np.isnan(d["Dis"][0]) and np.isnan(d["Dis mean"][0])                 # no true body: undefined
    assert d["Dis mean"][2] == pytest.approx(5.0 / 3)


def test_a_blown_up_prediction_gives_nan_not_a_number_that_looks_fine():
    truth, kin, radius = trajectory()
    pred = truth.copy()
    pred[2, 1] = np.nan
    metrics = SlideMetrics(kin, radius)
    assert np.isnan(metrics(pred)["Slide Num"][2]) and metrics.compare(pred, truth)["Dis"][2] == np.inf
    assert metrics(pred)["Slide Num"][1] == 1
