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
                  schedule=dem.RecordingSchedule(start=100, every=50, frames=3))
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
        deck.record_deck(_setup(schedule=dem.RecordingSchedule(start=120, every=50, frames=3)))


def _platen_setup(**extra) -> dem.Setup:
    """Particle 1 (species 0) a moving wall, particle 2 (species 2) a one-atom platen, particle 3 soil."""
    x = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.2], [0.0, 0.0, 0.1]])
    groups = {"lower": np.array([True, False, False]), "platen": np.array([False, True, False])}
    particles = dem.Particles(x, np.full(3, 0.01), np.array([0, 2, 1]), groups)
    fields = dict(particles=particles, kinematic_species=(0, 2), n_species=3,
                  motions=(dem.Motion("lower", (0.1, 0.0, 0.0), from_record=True),),
                  platen=dem.Platen("platen", mass=2.0, force=-40.0, axis=2, ramp=50),
                  force_groups=("lower", "platen"), force_samples=10)
    fields.update(extra)
    return _setup(**fields)


def test_a_platen_moves_rigidly_along_z_under_its_ramped_load():
    text = deck.record_deck(_platen_setup())
    lines = text.splitlines()
    assert "set             group platen mass 2" in lines
    assert 'variable        platen_load equal "-40*(step/50*(step<50)+(step>=50))"' in lines
    order = [next(i for i, line in enumerate(lines) if line.startswith(f"fix             {name} "))
             for name in ("platen_integrate", "platen_load", "platen_gravity", "platen_across")]
    assert order == sorted(order)                         # the mean force, then gravity, then none across z
    assert "fix             platen_integrate platen nve" in lines           # no rotation integrated
    assert "fix             platen_load platen aveforce NULL NULL v_platen_load" in lines
    assert "fix             platen_across platen setforce 0.0 0.0 NULL" in lines
    assert "neigh_modify    delay 0 every 1 check yes exclude type 1 1 exclude type 1 3 exclude type 3 3" in lines
    assert "group           recorded union moving motion0 platen" in lines


def test_a_motion_from_the_record_starts_after_the_run_up():
    lines = deck.record_deck(_platen_setup()).splitlines()
    run_up = lines.index("run             100")
    move = next(i for i, line in enumerate(lines) if line.startswith("fix             motion0 motion0 move"))
    assert move > run_up


def test_group_forces_are_averaged_over_the_frame_interval():
    lines = deck.record_deck(_platen_setup()).splitlines()
    assert "compute         force0 force0 reduce sum fx fy fz" in lines
    assert ("fix             groupforce all ave/time 5 10 50 c_force0[1] c_force0[2] c_force0[3] "
            "f_platen_load[1] f_platen_load[2] f_platen_load[3]") in lines
    assert deck.group_force_columns(_platen_setup(), "platen") == [f"f_groupforce[{k}]" for k in (4, 5, 6)]
    with pytest.raises(dem.UnsupportedSetup, match="force samples"):
        deck.record_deck(_platen_setup(force_samples=7))


def test_a_perturbation_splits_the_window_at_its_frame_around_the_displacement(tmp_path):
    """Frame 1 of 3 (50 steps apart, after a 100-step run-up): a run to it, the per-atom displacement of the moving
    particle from one file per axis (atom id and 17 digits: exact), then the rest; the atom map the files need is
    the only other line, and a deck without a perturbation has neither."""
    moved = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0e-7 / 3, -2.5e-8, 1.0 / 7.0 * 1e-6]])   # 3 moves
    setup = _setup(perturbation=dem.Perturbation(frame=1, displacement=moved))
    text = deck.record_deck(setup)
    assert text.splitlines()[-6:] == [
        "run             50", "variable        perturb_x atomfile perturbation_x.txt",
        "variable        perturb_y atomfile perturbation_y.txt",
        "variable        perturb_z atomfile perturbation_z.txt",
        "displace_atoms  moving move v_perturb_x v_perturb_y v_perturb_z units box", "run             50"]
    assert "atom_modify     map array" in text and "atom_modify" not in deck.record_deck(_setup())
    deck.write_perturbation(tmp_path, setup)
    for a, axis in enumerate("xyz"):
        lines = (tmp_path / f"perturbation_{axis}.txt").read_text().splitlines()
        assert lines[1] == "1" and lines[2].split()[0] == "3" and float(lines[2].split()[1]) == moved[2, a]


def test_a_2d_perturbation_moves_in_the_plane_only():
    x = np.array([[0.0, 0.0], [0.1, 0.0]])
    setup = _setup(particles=dem.Particles(x, np.full(2, 0.01), np.array([0, 1])), lower=np.full(2, -1.0),
                   upper=np.full(2, 1.0), schedule=dem.RecordingSchedule(start=0, every=50, frames=4),
                   perturbation=dem.Perturbation(frame=2, displacement=np.array([[0.0, 0.0], [1e-7, 2e-7]])))
    window = deck.record_deck(setup).splitlines()[-5:]
    assert window == ["run             100", "variable        perturb_x atomfile perturbation_x.txt",
                      "variable        perturb_y atomfile perturbation_y.txt",
                      "displace_atoms  moving move v_perturb_x v_perturb_y 0 units box", "run             50"]
