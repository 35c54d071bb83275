"""The LAMMPS deck written from a Setup: one contact law (no tangential dashpot, as YADE), moving kinematic
groups by `fix move`, a tilted gravity, and recording that starts on a dump step."""

import math

import numpy as np
import pytest

from generators import dem
from generators.lammps import deck


def _setup(**extra) -> dem.Setup:
    x = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.0, 0.1]])
    groups = {"lower": np.array([True, False, False])}
    c = dem.Contact(young=1e7, kn=1e5, kt_over_kn=0.3, restitution=0.5, friction=0.4)
    fields = dict(name="t", particles=dem.Particles(x, np.full(3, 0.01), np.array([0, 0, 1]), groups),
                  nominal_radius=0.01, kinematic_species=(0,), n_species=2, density=2650.0, gravity=9.81, contact=c,
                  dt=1e-6, dt_limit=1e-5, lower=np.full(3, -1.0), upper=np.full(3, 1.0), max_overlap=0.5,
                  schedule=dem.Record(start=100, every=50, frames=3))
    fields.update(extra)
    return dem.Setup(**fields)


def test_tangential_contact_has_no_dashpot():
    model = deck.contact_model(_setup().contact, 2650.0, 0.01, 3)
    assert "tangential linear_history 30000 0.0 0.4" in model


def test_a_motion_moves_its_group_by_id_and_is_recorded():
    text = deck.record_deck(_setup(motions=(dem.Motion("lower", (0.1, 0.0, 0.0)),)))
    assert "group           motion0 id 1\n" in text
    assert "fix             motion0 motion0 move linear 0.1 0 0" in text.replace("0.0 ", "0 ").replace("0.0\n", "0\n")
    assert "group           recorded union moving motion0" in text
    assert "dump            frames recorded custom 50" in text
    assert "compute         force kinematic reduce sum fx fy fz" in text


def test_a_motion_of_moving_particles_is_refused():
    with pytest.raises(dem.UnsupportedSetup, match="not of a kinematic species"):
        deck.record_deck(_setup(particles=dem.Particles(np.zeros((3, 3)), np.full(3, 0.01), np.array([0, 1, 1]),
                                                         {"lower": np.array([False, True, False])}),
                                motions=(dem.Motion("lower", (0.1, 0.0, 0.0)),)))


def test_tilted_gravity_points_down_the_incline():
    text = deck.record_deck(_setup(tilt=math.radians(30.0)))
    assert f"gravity 9.81 vector {math.sin(math.radians(30.0)):.12g} 0 {-math.cos(math.radians(30.0)):.12g}" in text


def test_recording_must_start_on_a_dump_step():
    with pytest.raises(dem.UnsupportedSetup, match="not a multiple of the frame interval"):
        deck.record_deck(_setup(schedule=dem.Record(start=120, every=50, frames=3)))
