"""The LAMMPS driver on tiny real runs of a few discs whose motion is known in closed form: free flight under
gravity (recorded frames, read back from the run folder as dumped, energies, a perturbation's shift), resting on
a wall (settled overlap m g / kn), a run whose disc leaves the domain (a named blow-up), and what it refuses."""

import dataclasses

import numpy as np
import pytest

from generators import blowup, dem
from generators.lammps import deck, driver, io, runner

from ..discs import DT, KN, RADIUS, V0, X0, G, disc_mass, settling_on_a_wall
from ..discs import setup as _setup

pytestmark = pytest.mark.engine

START, EVERY, FRAMES = 100, 100, 4


def _flight(t):
    """[T, 3, 2] positions in free flight: x = x0 + vx t, y = y0 + vy t - g t^2 / 2 (velocity Verlet is exact
    under a constant force); the fixed disc stays at x0."""
    t = np.asarray(t, float)[:, None, None]
    pos = X0 + V0 * t + np.array([0.0, -0.5 * G]) * t**2
    pos[:, 0] = X0[0]
    return pos


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    setup = _setup(X0, RADIUS, [0, 1, 1], dem.RecordingSchedule(START, EVERY, FRAMES), velocity=V0)
    workdir = tmp_path_factory.mktemp("flight")
    frames, run = driver.run_recording(setup, workdir)
    return setup, workdir, frames, run


def test_recorded_frames_follow_free_flight_at_the_recorded_steps(flight):
    setup, _, frames, _ = flight
    np.testing.assert_array_equal(frames.step, START + EVERY * np.arange(FRAMES))
    np.testing.assert_allclose(frames.time, frames.step * DT)
    np.testing.assert_allclose(frames.position, _flight(frames.time), rtol=0, atol=1e-9)
    np.testing.assert_allclose(frames.radius, RADIUS)
    np.testing.assert_allclose(frames.mass[1:], disc_mass(RADIUS[1:]), rtol=1e-9)


def test_kinetic_energy_and_the_force_on_the_fixed_disc(flight):
    _, _, frames, _ = flight
    # KE of the free discs at t: sum 0.5 m (vx^2 + (g t)^2); no contact, so no rotation and no force on the fixed one
    m = disc_mass(RADIUS[1:])
    expected = [0.5 * (m * (V0[1:, 0] ** 2 + (G * t) ** 2)).sum() for t in frames.time]
    np.testing.assert_allclose(frames.kinetic_energy, expected, rtol=1e-6)
    np.testing.assert_array_equal(frames.kinematic_force, np.zeros((FRAMES, 2)))
    assert frames.group_force == {}


def test_read_raw_gives_the_dumped_positions_and_the_fixed_disc_from_the_data_file(flight):
    setup, workdir, frames, _ = flight
    raw = driver.read_raw(workdir, DT)
    dumps = io.read_dump(workdir / deck.FRAMES)
    assert [step for step, _ in dumps] == list(raw["step"])
    for f, (_, table) in enumerate(dumps):
        assert list(table["id"]) == [2, 3]                       # only the moving discs are dumped
        np.testing.assert_array_equal(raw["position"][f, 1:], table[["x", "y"]].to_numpy(float))
        np.testing.assert_array_equal(raw["position"][f, 0], X0[0])
    np.testing.assert_array_equal(raw["position"], frames.position)
    np.testing.assert_array_equal(raw["recorded"], [False, True, True])
    np.testing.assert_array_equal(raw["species"], [0, 1, 1])
    np.testing.assert_allclose(raw["time"], raw["step"] * DT)


def test_the_run_counts_its_steps_and_times_its_window(flight):
    _, workdir, _, run = flight
    assert run.engine == "lammps" and run.ranks == 1
    assert run.steps == START + EVERY * (FRAMES - 1)              # the run-up and the recorded window
    loops = io.loop_times(workdir / "log.lammps")
    assert [n for _, n in loops] == [START, EVERY * (FRAMES - 1)]
    assert run.window_seconds == loops[-1][0] and run.runup_seconds == loops[0][0]


def test_a_perturbation_shifts_the_flight_after_its_frame_and_keeps_the_velocities(tmp_path):
    shift = np.array([[0.0, 0.0], [1e-3, -2e-3], [-5e-4, 0.0]])
    setup = _setup(X0, RADIUS, [0, 1, 1], dem.RecordingSchedule(START, EVERY, FRAMES), velocity=V0,
                   perturbation=dem.Perturbation(frame=1, displacement=shift))
    frames, run = driver.run_recording(setup, tmp_path)
    expected = _flight(frames.time)
    expected[2:] += shift                                         # frames 0..1 are the unperturbed run's
    np.testing.assert_allclose(frames.position, expected, rtol=0, atol=1e-9)
    m = disc_mass(RADIUS[1:])
    # a displacement changes no velocity: the energies are the unperturbed run's
    np.testing.assert_allclose(frames.kinetic_energy,
                               [0.5 * (m * (V0[1:, 0] ** 2 + (G * t) ** 2)).sum() for t in frames.time], rtol=1e-6)
    assert run.steps == START + EVERY * (FRAMES - 1)


def test_settled_discs_rest_on_the_wall_with_their_weight_s_overlap(tmp_path):
    # two free discs of different radii above a wall at y = 0: at rest kn (r - y) = m g, so y = r - m g / kn
    radius = np.array([0.01, 0.02])
    setup = settling_on_a_wall(radius)
    groups = {"probe": np.array([False, True])}
    setup = dataclasses.replace(setup, particles=dataclasses.replace(setup.particles, groups=groups))
    settled, run = driver.settle(setup, tmp_path)
    np.testing.assert_allclose(settled.radius, radius)
    np.testing.assert_allclose(settled.x[:, 1], radius - disc_mass(radius) * G / KN, rtol=0, atol=2e-7)
    np.testing.assert_allclose(settled.x[:, 0], setup.particles.x[:, 0], atol=1e-9)    # a vertical fall
    assert settled.groups is groups and list(settled.species) == [0, 0]
    assert 0 < run.steps < 2.0 / DT and not (tmp_path / deck.PACKING).exists()


def test_a_disc_leaving_the_domain_is_a_named_blow_up_at_its_frame(tmp_path):
    # thrown at 50 m/s from x = -0.25 it crosses the domain's upper x = 1 at t = 1.25 / 50 = 0.025 s (step 250);
    # LAMMPS finds the lost atom at its next thermo step, 300, so its last thermo output is step 200: frame
    # (200 - 100) / 100 = 1. The fixed disc is out of the way, below.
    x = np.array([[0.0, -0.5], [-0.25, 0.0]])
    setup = _setup(x, [0.01, 0.01], [0, 1], dem.RecordingSchedule(100, 100, 5),
                   velocity=np.array([[0.0, 0.0], [50.0, 0.0]]), gravity=0.0)
    with pytest.raises(blowup.BlowUp, match="simulation tiny blew up at frame 1: particles left the domain") as info:
        driver.run_recording(setup, tmp_path)
    assert info.value.frame == 1


def test_blow_ups_before_the_first_frame_and_of_non_finite_values_are_named():
    setup = _setup(X0, RADIUS, [0, 1, 1], dem.RecordingSchedule(START, EVERY, FRAMES))
    early = driver._blowup(setup, runner.LammpsError("ERROR: Lost atoms: original 3 current 2", 50), START, EVERY)
    assert early.frame == 0 and "after DEM step 50" in early.cause and "in the run-up" in early.cause
    late = driver._blowup(setup, runner.LammpsError("ERROR: Non-numeric atom coords", 350), START, EVERY)
    assert late.frame == (350 - START) // EVERY == 2 and late.cause.startswith("non-finite values")


def test_threads_and_unavailable_ranks_are_refused_by_name(tmp_path, monkeypatch):
    setup = _setup(X0, RADIUS, [0, 1, 1], dem.RecordingSchedule(START, EVERY, FRAMES))
    with pytest.raises(dem.UnsupportedSetup, match="tiny: threads = 2; LAMMPS runs one thread per MPI rank"):
        driver.run_recording(setup, tmp_path, threads=2)
    assert list(tmp_path.iterdir()) == []                         # refused before anything is written
    assert driver.ranks_problem(1) is None
    monkeypatch.setenv(runner.MPIRUN_ENV, str(tmp_path / "no-mpirun"))
    assert "mpirun -np 4" in driver.ranks_problem(4) and runner.MPIRUN_ENV in driver.ranks_problem(4)
