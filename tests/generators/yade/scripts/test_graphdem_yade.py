"""graphdem's YADE script on two tiny real jobs (through the YADE driver) whose motion is known in closed form:
discs in free flight with a moved fixed disc and a perturbation after a frame (YADE's integrator updates the
velocity before the position), and discs settled on a wall (overlap m g / kn, kn scaled by the disc's radius)."""

import numpy as np
import pytest

from generators import dem
from generators.yade import driver

from ...discs import DT, KN, R_NOMINAL, RADIUS, V0, X0, G, disc_mass, settling_on_a_wall
from ...discs import setup as _setup

pytestmark = pytest.mark.engine

START, EVERY, FRAMES = 100, 100, 4
FLOOR_V = 0.5                                       # m/s along x, the fixed disc's motion
SHIFT = np.array([[0.0, 0.0], [1e-3, -2e-3], [-5e-4, 0.0]])


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    particles = dem.Particles(X0, RADIUS, np.array([0, 1, 1]), {"floor": np.array([True, False, False])})
    setup = _setup(X0, RADIUS, [0, 1, 1], dem.RecordingSchedule(START, EVERY, FRAMES), velocity=V0,
                   particles=particles, motions=(dem.Motion("floor", (FLOOR_V, 0.0)),),
                   perturbation=dem.Perturbation(frame=1, displacement=SHIFT))
    return driver.run_recording(setup, tmp_path_factory.mktemp("flight"))


def test_free_flight_moved_disc_and_perturbation(flight):
    frames, _ = flight
    np.testing.assert_array_equal(frames.step, START + EVERY * np.arange(FRAMES))
    np.testing.assert_allclose(frames.time, frames.step * DT)
    n = frames.step[:, None]
    # velocity first, then position: after n steps v = -g n dt and y = y0 - g dt^2 (1 + 2 + ... + n)
    # = y0 - g dt^2 n (n + 1) / 2; x = x0 + vx n dt
    expected = np.empty((FRAMES, 3, 2))
    expected[:, 1:, 0] = X0[1:, 0] + V0[1:, 0] * n * DT
    expected[:, 1:, 1] = X0[1:, 1] - G * DT**2 * n * (n + 1) / 2
    expected[:, 0] = X0[0] + np.c_[FLOOR_V * frames.time, np.zeros(FRAMES)]   # the fixed disc moved, not falling
    expected[2:] += SHIFT                          # displaced right after frame 1
    np.testing.assert_allclose(frames.position, expected, rtol=0, atol=1e-12)


def test_energy_mass_and_force_of_the_flight(flight):
    frames, run = flight
    m = disc_mass(RADIUS)
    np.testing.assert_allclose(frames.mass, m, rtol=1e-9)
    # the free discs' KE at t: sum 0.5 m (vx^2 + (g t)^2), the perturbation changing no velocity
    expected = [0.5 * (m[1:] * (V0[1:, 0] ** 2 + (G * t) ** 2)).sum() for t in frames.time]
    np.testing.assert_allclose(frames.kinetic_energy, expected, rtol=1e-9)
    np.testing.assert_array_equal(frames.kinematic_force, np.zeros((FRAMES, 2)))     # no contact
    assert run.engine == "yade" and run.steps == START + EVERY * (FRAMES - 1)
    assert run.notes == {"servers_closed": 0, "listening_sockets": []}


def test_settled_discs_rest_on_the_wall_with_their_weight_s_overlap(tmp_path):
    # a wall meets a disc of radius r with kn 2 r / (r + r_nominal): at rest y = r - m g / (kn 2 r / (r + r_nom))
    radius = np.array([0.01, 0.02])
    setup = settling_on_a_wall(radius)
    settled, run = driver.settle(setup, tmp_path)
    wall_kn = KN * 2 * radius / (radius + R_NOMINAL)
    # the drag damps the heavier disc more slowly: 1e-6 m of its 2.5e-4 m overlap may be left when both stop
    np.testing.assert_allclose(settled.x[:, 1], radius - disc_mass(radius) * G / wall_kn, rtol=0, atol=1e-6)
    np.testing.assert_allclose(settled.x[:, 0], setup.particles.x[:, 0], atol=1e-12)
    assert 0 < run.steps < 2.0 / DT and not (tmp_path / "settle.npz").exists()
