import numpy as np
import pytest

from generators import blowup

LOWER, UPPER = np.zeros(2), np.array([10.0, 10.0])


def resting_pair(frames=4):
    x = np.array([[2.0, 2.0], [3.0, 2.0], [6.0, 6.0]])        # touching pair, one loose disc
    return np.repeat(x[None], frames, axis=0).copy(), np.array([0.5, 0.5, 0.5]), np.zeros(3, bool)


def test_clean_trajectory_is_not_flagged():
    pos, r, kin = resting_pair()
    blowup.check_trajectory("s", pos, r, kin, LOWER, UPPER, max_overlap=0.1)


def test_non_finite_value_is_caught_with_frame():
    pos, r, kin = resting_pair()
    pos[2, 1, 0] = np.nan
    with pytest.raises(blowup.BlowUp, match="simulation s blew up at frame 2: non-finite position of particle 1"):
        blowup.check_trajectory("s", pos, r, kin, LOWER, UPPER, 0.1)


def test_escape_is_caught_with_frame():
    pos, r, kin = resting_pair()
    pos[3, 2] = [6.0, 12.0]
    with pytest.raises(blowup.BlowUp, match="frame 3: particle 2 left the domain"):
        blowup.check_trajectory("s", pos, r, kin, LOWER, UPPER, 0.1)


def test_overlap_above_limit_is_caught():
    pos, r, kin = resting_pair()
    pos[1, 1] = [2.6, 2.0]                        # distance 0.6: overlap 0.4 = 0.8 radii
    with pytest.raises(blowup.BlowUp, match="frame 1: overlap of 0.800 radii"):
        blowup.check_trajectory("s", pos, r, kin, LOWER, UPPER, 0.5)


def test_overlap_between_two_kinematic_particles_is_geometry():
    pos, r, _ = resting_pair()
    pos[:, 1] = [2.2, 2.0]
    blowup.check_trajectory("s", pos, r, np.array([True, True, False]), LOWER, UPPER, 0.1)
    assert blowup.max_overlap_fraction(pos[0], r, np.zeros(3, bool)) == pytest.approx(1.6)


def test_energy_that_only_dissipates_is_not_flagged():
    kinetic = np.array([0.0, 5.0, 8.0, 3.0])
    potential = np.array([100.0, 93.0, 88.0, 86.0])          # falling: potential turned into motion and heat
    blowup.check_energy("s", kinetic, potential, scale=10.0, max_gain=0.1)


def test_energy_growing_without_a_source_is_caught_with_frame():
    kinetic = np.array([0.0, 5.0, 30.0, 1e6])                  # an integrator pumping energy in
    potential = np.array([100.0, 95.0, 90.0, 90.0])
    with pytest.raises(blowup.BlowUp, match=r"frame 2: mechanical energy grew by 2 x the reference energy 10 J"):
        blowup.check_energy("s", kinetic, potential, scale=10.0, max_gain=0.1)
    with pytest.raises(blowup.BlowUp, match="frame 1: mechanical energy grew by inf"):
        blowup.check_energy("s", np.array([0.0, np.inf]), np.array([1.0, 1.0]), scale=1.0, max_gain=0.1)
