"""Restitution measured in a real LAMMPS collision at the scene's own time step."""

import pytest

from generators import contact
from generators.lammps import collision
from generators.scenes import slide

pytestmark = pytest.mark.engine


@pytest.mark.parametrize("restitution", [0.3, 0.5, 0.8])
def test_two_disc_collision_matches_configured_restitution(ci_slide, restitution):
    cfg = dict(ci_slide, restitution=restitution)
    dt, _, _ = slide.dem_step(cfg, "test")
    r_mean = 0.5 * sum(cfg["radius"])
    e_input = contact.lammps_tsuji_input(restitution)
    for radius in cfg["radius"]:                     # lightest and heaviest discs of the scene
        for speed in (0.5, 5.0):
            measured = collision.collision_restitution(
                e_input, cfg["young"], radius, cfg["density"], dt, cfg["kt_over_kn"], speed=speed,
                kn_radius=r_mean)
            assert measured == pytest.approx(restitution, rel=0.02), (radius, speed, measured)


def test_uncorrected_tsuji_input_would_miss():
    """Documents why the driver inverts Tsuji's polynomial: asking LAMMPS for 0.5 gives 0.58."""
    dt = 0.005 * contact.stable_time_step(contact.disc_mass(2650.0, 1.0), 1e9)
    measured = collision.collision_restitution(0.5, 1e9, 1.0, 2650.0, dt, kt_over_kn=0.2857)
    assert measured == pytest.approx(0.581, abs=0.005)
