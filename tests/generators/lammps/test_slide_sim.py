"""A real, tiny LAMMPS slide simulation: settled, triggered, converted to H5MD and checked."""

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from generators import contact, convert, engine, h5md, sweep
from generators.scenes import slide

pytestmark = pytest.mark.engine
DROP_HEIGHT = 75.0


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    from generators import config
    cfg = config.load({"scale": "ci", "slide": {
        "settle_time": 4.0, "frames": 8, "frame_interval": 0.1, "record_start": 0.0}})["slide"]
    root = tmp_path_factory.mktemp("slide")
    params = slide.SCENE.packing_params(cfg, 0)
    packing = root / "packing"
    engine.prepare(slide.SCENE, "lammps", params, packing)
    # One extra disc high above the plateau: airborne for the whole recorded window.
    table = pd.read_csv(packing / engine.PACKING_FILE)
    drop = {"species": slide.STABLE, "radius": cfg["radius"][0], "x": 10.0, "y": DROP_HEIGHT}
    pd.concat([table, pd.DataFrame([drop])]).to_csv(packing / engine.PACKING_FILE, index=False)
    row = sweep.build("slide", cfg).iloc[0].to_dict()
    engine.simulate(slide.SCENE, row, packing, root / "raw")
    traj = h5md.read(convert.convert(root / "raw", root / "sim.h5"))
    return {"cfg": cfg, "row": row, "traj": traj, "table": table, "root": root, "packing": packing}


def test_particle_count_constant_and_matches_packing(tiny):
    traj = tiny["traj"]
    assert traj.position.shape == (8, len(tiny["table"]) + 1, 2)
    assert traj.kinematic.sum() == (tiny["table"]["species"] == slide.BEDROCK).sum()


def test_kinematic_particles_never_move(tiny):
    traj = tiny["traj"]
    kin = traj.kinematic
    assert np.array_equal(traj.position[:, kin], np.repeat(traj.position[:1, kin], 8, axis=0))
    bedrock = tiny["table"][tiny["table"]["species"] == slide.BEDROCK][["x", "y"]].to_numpy()
    np.testing.assert_allclose(traj.position[0, kin], bedrock, atol=1e-5)


def test_no_moving_particle_leaves_the_domain(tiny):
    traj = tiny["traj"]
    moving = traj.position[:, ~traj.kinematic]
    assert np.all(moving >= traj.box_lower) and np.all(moving <= traj.box_upper)


def test_airborne_particle_falls_at_g(tiny):
    traj = tiny["traj"]
    y = traj.position[:, -1, 1].astype(np.float64)
    dt = np.diff(traj.time)
    assert np.allclose(dt, tiny["row"]["frame_interval"], rtol=0.01)
    accel = np.diff(np.diff(y)) / dt[0] ** 2
    assert accel == pytest.approx(-tiny["cfg"]["gravity"], rel=0.01)
    assert y[-1] < DROP_HEIGHT and np.ptp(traj.position[:, -1, 0]) < 1e-4    # no horizontal force


def test_frames_are_timed_and_provenance_recorded(tiny):
    traj = tiny["traj"]
    assert traj.time[0] == 0.0 and np.all(np.diff(traj.time) > 0)
    p = traj.parameters
    assert p["engine"] == "lammps" and "29 Sep 2021" in p["engine_version"]
    assert p["engine_command"].split()[0].endswith("lmp") and p["engine_wall_time"] > 0
    assert p["young"] == tiny["cfg"]["young"] and p["id"] == tiny["row"]["id"]
    assert p["dem_time_step"] <= p["dem_time_step_limit"]
    assert "kinetic_energy" in traj.observables
    assert set(np.unique(traj.species)) <= {0, 1, 2}


def test_trigger_makes_a_weak_layer(tiny):
    traj = tiny["traj"]
    assert (traj.species == slide.WEAK).sum() > 0 and (traj.species == slide.STABLE).sum() > 0


def _simulate_cli(row, packing, out):
    return subprocess.run([sys.executable, "-m", "graphdem", "simulate", "--scene", "slide",
                           "--sim", json.dumps(row), "--packing", str(packing), "--out", str(out)],
                          capture_output=True, text=True)


def test_unstable_time_step_is_refused_with_both_numbers(tiny, tmp_path):
    dt, limit, _ = contact.time_step(tiny["cfg"], "x", 2)
    row = dict(tiny["row"], dt=2 * limit)
    proc = _simulate_cli(row, tiny["packing"], tmp_path / "raw")
    assert proc.returncode == 1
    assert f"{2 * limit:.4g}" in proc.stderr and f"{limit:.4g}" in proc.stderr and row["id"] in proc.stderr
    assert list(tmp_path.iterdir()) == []


def test_blow_up_names_sim_frame_cause_and_leaves_nothing(tiny, tmp_path):
    row = dict(tiny["row"], max_overlap=1e-9)     # any contact at all counts as a blow-up here
    proc = _simulate_cli(row, tiny["packing"], tmp_path / "raw")
    assert proc.returncode == 1
    assert f"simulation {row['id']} blew up at frame 0: overlap of" in proc.stderr
    assert list(tmp_path.iterdir()) == []
