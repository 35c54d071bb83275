"""Plausibility measures of a trajectory: overlaps against hand-computed values, particles outside the box or
through a wall, the kinetic energy of a known motion."""

import numpy as np
import pytest

from evaluation.metrics import plausibility


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
    # disc 0 starts 0.2 radii into the wall disc and moves along it: in contact, not through it
    assert np.isnan(out["Through wall"][0]) and out["Through wall"][1] == 0.0
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


def _floor_run(path: list[tuple[float, float]]) -> np.ndarray:
    """[T, N, 2] frames of a row of fixed unit discs (centres at y = 1, 1.8 apart: no gap a unit disc fits
    through) and one moving unit disc (the last) at the positions ``path``."""
    floor = np.array([[x, 1.0] for x in np.arange(-5.4, 5.5, 1.8)])
    return np.stack([np.vstack([floor, [point]]) for point in path])


def _through(frames: np.ndarray) -> np.ndarray:
    kinematic = np.ones(frames.shape[1], bool)
    kinematic[-1] = False
    return plausibility.per_frame(frames, np.ones(frames.shape[1]), np.ones(frames.shape[1]), kinematic,
                                  np.array([-10.0, -10.0]), np.array([10.0, 10.0]), 0.1)["Through wall"]


def test_a_disc_that_passes_the_floor_counts_once_and_one_that_stays_above_it_never():
    # 3.5 radii down in one step, from above the floor to under its centres (still inside the box): through it
    np.testing.assert_array_equal(_through(_floor_run([(0.7, 3.2), (0.7, -0.3), (0.7, -0.5)]))[1:], [1.0, 0.0])
    # rolling along the floor from notch to notch (the notches at y = 1 + sqrt(4 - 0.81), 1.8 apart), 1.8
    # radii per frame, touching the floor discs all the way, then bouncing up: never through
    notch = 1.0 + np.sqrt(4.0 - 0.81)
    rolling = [(-3.6 + 1.8 * t + 0.9, notch) for t in range(5)] + [(4.5, 4.0)]
    assert (_through(_floor_run(rolling))[1:] == 0.0).all()
    # pressed 0.6 radii into the floor from the notch: deep, but on the near side (Max overlap's, not this one's)
    assert _through(_floor_run([(0.9, notch), (0.9, notch - 0.6)]))[1] == 0.0


def test_a_moving_wall_that_sweeps_through_a_resting_disc_counts_it():
    # the wall disc (0) moves 5 radii along x through a disc (1) resting in its way: relative motion counts
    frames = np.array([[[-3.0, 0.0], [0.0, 0.0]], [[2.0, 0.0], [0.0, 0.0]]])
    out = plausibility.per_frame(frames, np.ones(2), np.ones(2), np.array([True, False]), np.array([-9.0, -9.0]),
                                 np.array([9.0, 9.0]), 0.1)
    assert out["Through wall"][1] == 1.0
    # without kinematic particles (the meteorite) nothing is a wall
    free = plausibility.per_frame(frames, np.ones(2), np.ones(2), np.zeros(2, bool), np.array([-9.0, -9.0]),
                                  np.array([9.0, 9.0]), 0.1)
    assert free["Through wall"][1] == 0.0
