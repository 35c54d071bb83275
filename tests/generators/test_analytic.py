"""Analytic checks of both engines' drivers on the same engine-neutral Setups: free fall, head-on
restitution at each scene's own time step, a disc or sphere sliding and rolling down an incline, and
a resting column's weight on its base. LAMMPS and YADE must each meet the closed-form answer."""

from __future__ import annotations

import math

import numpy as np
import pytest

from generators import collision, config, contact, dem, engine, engines, scenes

pytestmark = pytest.mark.engine

ENGINES = engines.NAMES          # every registered engine (generators/engines.py)
RADIUS, DENSITY, G = 0.01, 2650.0, 9.81


def _contact(dim: int, friction: float = 0.5, restitution: float = 0.5) -> dem.Contact:
    kn = 1.0e5 if dim == 2 else 1.0e4
    return dem.Contact(young=kn / RADIUS, kn=kn, kt_over_kn=0.2857, restitution=restitution, friction=friction)


def _mass(dim: int) -> float:
    return contact.particle_mass(DENSITY, RADIUS, dim)


def _setup(dim: int, x: np.ndarray, c: dem.Contact, schedule: dem.RecordingSchedule, species=None, kinematic=(),
           walls=(), tilt: float = 0.0, span: float = 2.0) -> dem.Setup:
    n = len(x)
    limit = contact.stable_time_step(_mass(dim), c.kn)
    return dem.Setup(name="analytic", particles=dem.Particles(np.asarray(x, float), np.full(n, RADIUS),
                                                                np.zeros(n, int) if species is None else species),
                     nominal_radius=RADIUS, kinematic_species=kinematic, n_species=1 + len(kinematic), density=DENSITY,
                     gravity=G, contact=c, dt=0.02 * limit, dt_limit=limit, lower=np.full(dim, -span),
                     upper=np.full(dim, span), max_overlap=1.0, schedule=schedule, walls=walls, tilt=tilt)


def _record(setup: dem.Setup, engine_name: str, tmp_path) -> dem.Frames:
    frames, _ = engine.driver(engine_name).run_recording(setup, tmp_path)
    return frames


def _steps(dim: int, seconds: float) -> int:
    return int(round(seconds / (0.02 * contact.stable_time_step(_mass(dim), _contact(dim).kn))))


def _acceleration(t: np.ndarray, x: np.ndarray) -> float:
    """Least-squares a of x = x0 + v0 t + a t^2 / 2."""
    return 2.0 * float(np.polyfit(t - t[0], x, 2)[0])


@pytest.mark.parametrize("engine_name", ENGINES)
@pytest.mark.parametrize("dim", [2, 3])
def test_free_fall_follows_g_t2_over_2(engine_name, dim, tmp_path):
    every = _steps(dim, 0.02)
    setup = _setup(dim, np.zeros((1, dim)), _contact(dim), dem.RecordingSchedule(start=0, every=every, frames=11))
    frames = _record(setup, engine_name, tmp_path)
    t = frames.time - frames.time[0]
    drop = frames.position[0, 0, -1] - frames.position[:, 0, -1]
    assert drop[-1] > 0.15
    # exact up to a leapfrog start (YADE keeps v at half steps): at most g t dt apart
    assert np.all(np.abs(drop - 0.5 * G * t**2) <= G * t * setup.dt + 1e-12)
    assert _acceleration(frames.time, frames.position[:, 0, -1]) == pytest.approx(-G, rel=1e-4)
    np.testing.assert_allclose(frames.position[:, 0, :-1], 0.0, atol=1e-12)     # falls straight down


def _scene_setup(name: str) -> dem.Setup:
    """A Setup of the scene at its default scale: its contact, nominal radius and own time step."""
    cfg = config.load({"scale": "default"})[name]
    scene = scenes.get(name)
    return scene.settle_setup(scene.packings(cfg)[0])


@pytest.mark.parametrize("engine_name", ENGINES)
@pytest.mark.parametrize("scene_name", scenes.names())
def test_normal_restitution_within_2_percent_at_the_scene_time_step(engine_name, scene_name, tmp_path):
    """The scene's smallest moving pair (the stable limit is its) at three impact phases: the error moves with
    the phase by up to ~2 % at these steps (`graphdem restitution` over 13 phases, docs/performance.md)."""
    s = _scene_setup(scene_name)
    radius = collision.scene_pairs(s)["smallest"]
    e = collision.over_impact_phases(engine_name, s, radius, s.dt, 3, tmp_path)
    np.testing.assert_allclose(e, s.contact.restitution, rtol=0.02, err_msg=f"{scene_name} at {s.dt / s.dt_limit}")


def _on_incline(dim: int, friction: float, tilt: float) -> dem.Setup:
    c = _contact(dim, friction=friction)
    x = np.zeros((1, dim))
    x[0, -1] = RADIUS - _mass(dim) * G * math.cos(tilt) / c.kn       # resting overlap
    wall = dem.PlanarWall(axis=dim - 1, lower=0.0, upper=None)
    return _setup(dim, x, c, dem.RecordingSchedule(start=0, every=_steps(dim, 0.02), frames=16), walls=(wall,),
                  tilt=tilt)


@pytest.mark.parametrize("engine_name", ENGINES)
@pytest.mark.parametrize("dim", [2, 3])
def test_sliding_down_an_incline_at_g_sin_minus_mu_cos(engine_name, dim, tmp_path):
    tilt, mu = math.radians(30.0), 0.1       # tan 30 deg > 3 mu (disc) and 7/2 mu (sphere): it slides
    frames = _record(_on_incline(dim, mu, tilt), engine_name, tmp_path)
    a = _acceleration(frames.time[3:], frames.position[3:, 0, 0])
    assert a == pytest.approx(G * (math.sin(tilt) - mu * math.cos(tilt)), rel=0.01)


@pytest.mark.parametrize("engine_name", ENGINES)
@pytest.mark.parametrize("dim", [2, 3])
def test_rolling_without_slip_down_an_incline(engine_name, dim, tmp_path):
    tilt, mu = math.radians(30.0), 0.8       # friction enough to roll: 2/3 (disc) or 5/7 (sphere) of g sin
    frames = _record(_on_incline(dim, mu, tilt), engine_name, tmp_path)
    a = _acceleration(frames.time[3:], frames.position[3:, 0, 0])
    assert a == pytest.approx((2.0 / 3.0 if dim == 2 else 5.0 / 7.0) * G * math.sin(tilt), rel=0.01)


@pytest.mark.parametrize("engine_name", ENGINES)
@pytest.mark.parametrize("dim", [2, 3])
def test_resting_column_presses_its_base_with_its_weight(engine_name, dim, tmp_path):
    """Five particles stacked on a fixed one: at rest the base carries their weight, n m g (a pressure of
    n m g over the column's width 2 r)."""
    n = 5
    x = np.zeros((n + 1, dim))
    overlap = np.array([(n - k) * _mass(dim) * G / _contact(dim).kn for k in range(n)])   # spring k carries n - k
    x[1:, -1] = 2.0 * RADIUS * np.arange(1, n + 1) - np.cumsum(overlap)
    species = np.r_[1, np.zeros(n, int)]
    setup = _setup(dim, x, _contact(dim, restitution=0.2),
                   dem.RecordingSchedule(start=0, every=_steps(dim, 0.05), frames=8), species=species, kinematic=(1,))
    frames = _record(setup, engine_name, tmp_path)
    weight = n * _mass(dim) * G
    force = frames.kinematic_force[-1]
    assert force[-1] == pytest.approx(-weight, rel=1e-3)          # pressed downwards by the weight above
    assert np.abs(force[:-1]).max() < 1e-6 * weight
    width = 2.0 * RADIUS
    assert -force[-1] / width == pytest.approx(weight / width, rel=1e-3)
