"""A real, tiny LAMMPS meteorite impact: bed settled, meteorite launched, converted to H5MD and checked."""

import math

import numpy as np
import pytest

from generators import config, convert, engine, h5md, sweep
from generators.scenes import meteorite

pytestmark = pytest.mark.engine


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    cfg = config.load({"scale": "ci", "meteorite": {"bed_depth": 30.0, "frames": 8,
                                                    "evaluate": {"frames": None}}})["meteorite"]
    root = tmp_path_factory.mktemp("meteorite")
    engine.prepare(meteorite.SCENE, "lammps", meteorite.SCENE.packings(cfg)[0], root / "packing")
    row = sweep.build("meteorite", cfg).iloc[0].to_dict()          # 30 degrees, 60 m/s
    engine.simulate(meteorite.SCENE, row, root / "packing", root / "raw")
    traj = h5md.read(convert.convert(root / "raw", root / "sim.h5"))
    return {"cfg": cfg, "row": row, "traj": traj, "bed": engine.read_packing(root / "packing")}


def test_count_constant_two_types_nothing_kinematic(tiny):
    traj, bed = tiny["traj"], tiny["bed"]
    n_met = len(meteorite.meteorite_cluster(tiny["row"])[0])
    assert traj.position.shape == (8, len(bed.x) + n_met, 2)
    assert (traj.species == meteorite.METEORITE).sum() == n_met > 1
    assert not traj.kinematic.any()
    assert traj.parameters["scene"] == "meteorite" and traj.parameters["engine"] == "lammps"


def test_no_particle_leaves_the_domain(tiny):
    traj = tiny["traj"]
    assert np.all(traj.position >= traj.box_lower) and np.all(traj.position <= traj.box_upper)


def test_meteorite_momentum_before_contact_matches_speed_and_angle(tiny):
    """Frames 0 -> 1 are before contact (contact_frame = 3): ballistic flight, so the mean velocity over
    the interval is the launch velocity minus g dt / 2 vertically; within 1 % in speed and angle."""
    traj, row = tiny["traj"], tiny["row"]
    met = traj.species == meteorite.METEORITE
    dt = traj.time[1] - traj.time[0]
    mass = traj.mass[met]
    momentum = (mass[:, None] * (traj.position[1, met] - traj.position[0, met]) / dt).sum(axis=0)
    velocity = momentum / mass.sum() + np.array([0.0, 0.5 * row["gravity"] * dt])
    speed = np.linalg.norm(velocity)
    angle = math.degrees(math.atan2(-velocity[1], velocity[0]))
    assert speed == pytest.approx(row["speed"], rel=0.01)
    assert angle == pytest.approx(row["angle"], rel=0.01)


def test_bed_is_at_rest_before_contact_and_struck_after(tiny):
    traj = tiny["traj"]
    ground = traj.species == meteorite.GROUND
    before = np.abs(traj.position[2, ground] - traj.position[0, ground]).max()
    after = np.abs(traj.position[-1, ground] - traj.position[0, ground]).max()
    assert before < 0.01 * tiny["cfg"]["radius"][0]         # settled bed, untouched yet
    assert after > 10 * before


def test_recording_starts_before_contact_and_the_path_is_aimed_at_the_bed_top(tiny):
    """Frame 0 is before contact, contact comes within the window, and at contact_frame the cluster's
    lowest point is at the height of the bed's top near the middle (to the gravity sag g t^2 / 2)."""
    from generators.scenes.meteorite import MeteoriteMetrics
    traj, row, bed = tiny["traj"], tiny["row"], tiny["bed"]
    metrics = MeteoriteMetrics.for_trajectory(traj)
    position = np.asarray(traj.position, float)
    assert math.isnan(metrics.impact_x(position[:1]))
    assert not math.isnan(metrics.impact_x(position))
    met = traj.species == meteorite.METEORITE
    lowest = (position[row["contact_frame"], met, 1] - traj.radius[met]).min()
    top = meteorite.surface_height(bed, 0.5 * row["domain"][0], 2.0 * row["radius"][1])
    sag = 0.5 * row["gravity"] * (row["contact_frame"] * (traj.time[1] - traj.time[0])) ** 2
    assert lowest == pytest.approx(top - sag, abs=0.01)
