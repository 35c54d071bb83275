import numpy as np
import pytest

from generators import blowup, dem

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


def test_the_elastic_energy_of_pressed_pairs_and_walls_counts_each_contact_once():
    # three discs of radius 1 in a row: moving disc 1 presses kinematic disc 0 by 0.1 and moving disc 2 by 0.2
    x = np.array([[0.0, 0.0], [1.9, 0.0], [3.7, 0.0]])
    radius = np.ones(3)
    kinematic = np.array([True, False, False])
    stiffness = {(0, 1): 100.0, (1, 2): 10.0}
    energy = blowup.elastic_energy(x, radius, kinematic, lambda i, j: np.array(
        [stiffness[min(a, b), max(a, b)] for a, b in zip(i, j, strict=True)]))
    assert energy == pytest.approx(0.5 * 100.0 * 0.1 ** 2 + 0.5 * 10.0 * 0.2 ** 2)
    # a wall at y = 0.5 from above (upper) presses both moving discs by 0.5: 2 x 1/2 kn 0.25
    wall = dem.PlanarWall(1, None, 0.5)
    assert blowup.elastic_energy(x, radius, kinematic, lambda i, j: np.zeros(len(i)), (wall,), 4.0) == \
        pytest.approx(2 * 0.5 * 4.0 * 0.25)
    two_kinematic = blowup.elastic_energy(x[:2], radius[:2], np.array([True, True]), lambda i, j: np.ones(len(i)))
    assert two_kinematic == 0.0                                     # geometry, not a contact


def test_a_released_column_turning_its_contacts_energy_into_motion_is_not_a_blow_up():
    """Two discs pressed together at rest fly apart: kinetic energy from the spring, not from the integrator."""
    particles = dem.Particles(np.array([[0.0, 0.0], [1.8, 0.0]]), np.ones(2), np.zeros(2, int))
    kn = 50.0
    setup = dem.Setup(name="pair", particles=particles, nominal_radius=1.0, kinematic_species=(), n_species=1,
                      density=1.0, gravity=1.0, contact=contact_model(kn), dt=1e-3, dt_limit=1e-2,
                      lower=np.full(2, -5.0), upper=np.full(2, 5.0), max_overlap=0.5,
                      schedule=dem.RecordingSchedule(start=0, every=1, frames=2), max_energy_gain=0.1)
    apart = np.array([[[0.0, 0.0], [1.8, 0.0]], [[-0.5, 0.0], [2.3, 0.0]]])
    spring = 0.5 * kn * 0.2 ** 2                                    # 1 J: all of it turned into motion
    blowup.check_energy_of(setup, apart, np.ones(2), np.ones(2), np.array([0.0, spring]))
    # twice the spring's energy: a gain of 1 J over M g d = 1 x 2 x 2 = 4 J
    with pytest.raises(blowup.BlowUp, match="frame 1: mechanical energy grew by 0.25 x the reference energy 4 J"):
        blowup.check_energy_of(setup, apart, np.ones(2), np.ones(2), np.array([0.0, 2 * spring]))


def contact_model(kn: float) -> dem.Contact:
    return dem.Contact(young=kn, kn=kn, kt_over_kn=0.2857, restitution=0.5, friction=0.5)
