"""Plausibility measures of a trajectory: overlaps against hand-computed values, particles outside the box,
the kinetic energy of a known motion."""

import numpy as np
import pytest

from surrogate.metrics import plausibility


def _frames():
    # three discs of radius 1 and one kinematic wall disc (3); frame 0: discs 0 and 1 overlap by 0.5 radii, disc 0
    # and the wall by 0.2; frame 1: the discs move +0.1 in x, and disc 2 leaves the box through x = 10
    x0 = np.array([[0.0, 0.0], [1.5, 0.0], [9.95, 5.0], [0.0, -1.8]])
    x1 = x0 + np.array([0.1, 0.0])
    x1[3] = x0[3]                                       # the wall does not move
    return np.stack([x0, x1])


def test_overlaps_outside_and_energy_by_hand():
    radius = np.ones(4)
    mass = np.full(4, 2.0)
    kinematic = np.array([False, False, False, True])
    out = plausibility.per_frame(_frames(), radius, mass, kinematic, np.array([-5.0, -5.0]), np.array([10.0, 10.0]),
                                 frame_interval=0.1)
    # frame 0: pairs (0,1) overlap 0.5 and (0,3) overlap 0.2 radii; frame 1: (0,1) 0.5 and (0,3) |(0.1,1.8)| apart
    gap = 2.0 - np.hypot(0.1, 1.8)
    np.testing.assert_allclose(out["Max overlap"], [0.5, 0.5])
    np.testing.assert_allclose(out["P99 overlap"], [0.2 + 0.99 * 0.3, gap + 0.99 * (0.5 - gap)])
    np.testing.assert_array_equal(out["Outside box"], [0.0, 1.0])
    # three moving discs at 1 m/s: 3 * 1/2 * 2 * 1^2 = 3 J (per metre of depth)
    assert np.isnan(out["Kinetic energy"][0]) and out["Kinetic energy"][1] == pytest.approx(3.0)


def test_kinematic_pairs_are_geometry_and_a_non_finite_frame_is_nan():
    frames = _frames()
    kinematic = np.array([True, True, False, True])       # both overlapping pairs are now pairs of wall discs
    out = plausibility.per_frame(frames, np.ones(4), np.ones(4), kinematic, np.array([-5.0, -5.0]),
                                 np.array([20.0, 20.0]), 0.1)
    np.testing.assert_array_equal(out["Max overlap"], [0.0, 0.0])
    broken = frames.copy()
    broken[1, 2] = np.nan
    bad = plausibility.per_frame(broken, np.ones(4), np.ones(4), np.zeros(4, bool), np.array([-5.0, -5.0]),
                                 np.array([20.0, 20.0]), 0.1)
    assert all(np.isnan(bad[name][1]) for name in plausibility.NAMES)
    assert bad["Max overlap"][0] == pytest.approx(0.5)
