"""A real, tiny YADE direct-shear test: packing settled, lower box sheared, converted to H5MD and checked."""

import numpy as np
import pytest

from generators import config, convert, dem, engine, h5md, sweep
from generators.scenes import shear

pytestmark = pytest.mark.engine


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    cfg = config.load({"scale": "ci", "shear": {"radius": [0.008, 0.01], "wall_radius": 0.008, "frames": 6,
                                                   "model": {"history": 2}}})["shear"]
    root = tmp_path_factory.mktemp("shear")
    engine.prepare(shear.SCENE, "yade", shear.SCENE.packings(cfg)[0], root / "packing")
    table = sweep.build("shear", cfg)
    row = table.iloc[-1].to_dict()                          # the stiffest modulus, the largest displacement
    meta = engine.simulate(shear.SCENE, row, root / "packing", root / "raw")
    path = convert.convert(root / "raw", root / "sim.h5")
    return {"cfg": cfg, "row": row, "meta": meta, "traj": h5md.read(path), "path": path,
            "packing": engine.read_packing(root / "packing")}


def test_count_constant_types_soil_box_and_platen(tiny):
    traj, packing = tiny["traj"], tiny["packing"]
    platen = len(shear.platen_grid(tiny["cfg"]))
    flanges = len(shear.flanges(tiny["row"]).x)
    assert flanges > 0 and traj.position.shape == (6, len(packing.x) + flanges + platen, 3)
    assert set(np.unique(traj.species)) == {shear.BOX, shear.SOIL, shear.PLATEN}
    assert (traj.species == shear.PLATEN).sum() == platen
    assert np.array_equal(traj.kinematic, np.isin(traj.species, (shear.BOX, shear.PLATEN)))


def test_the_written_file_holds_the_shear_observables(tiny):
    """Read back from the H5MD file: one value per frame of each, the normal stress near the set value."""
    traj = tiny["traj"]
    for name in shear.OBSERVABLES:
        assert traj.observables[name].shape == (6,) and np.isfinite(traj.observables[name]).all()
    assert traj.observables["normal_stress"].mean() == pytest.approx(tiny["row"]["normal_stress"], rel=0.1)
    assert traj.observables["shear_displacement"][-1] == pytest.approx(tiny["row"]["displacement"], rel=1e-6)
    assert (traj.species == shear.SOIL).sum() > 10


def test_box_particles_follow_their_prescribed_motion_exactly(tiny):
    """Lower half (its trailing flange included): x0 + v t from frame 0 on (v chosen so the last frame is at exactly
    the displacement; held through the loading before it); upper half (its leading flange included): held."""
    traj, packing = tiny["traj"], tiny["packing"]
    both = packing.concat(shear.flanges(tiny["row"]))           # the sim's particles before the platen, in order
    n = len(both.x)
    lower = np.zeros(len(traj.species), bool)
    lower[:n] = both.groups[shear.LOWER]
    upper = np.zeros(len(traj.species), bool)
    upper[:n] = (both.species == shear.BOX) & ~both.groups[shear.LOWER]
    t = traj.time - traj.time[0]
    x0 = np.concatenate([both.x, np.zeros((len(traj.species) - n, 3))])
    expected = x0[lower][None] + np.outer(t, [traj.parameters["shear_speed"], 0.0, 0.0])[:, None, :]
    np.testing.assert_allclose(traj.position[:, lower], expected, rtol=0, atol=1e-7)      # float32 storage
    np.testing.assert_allclose(traj.position[:, upper], np.repeat(x0[upper][None], 6, axis=0), rtol=0, atol=1e-7)
    shift = traj.position[-1, lower, 0] - traj.position[0, lower, 0]
    np.testing.assert_allclose(shift, tiny["row"]["displacement"], rtol=1e-5)


def test_no_soil_escapes_the_box(tiny):
    traj, cfg = tiny["traj"], tiny["cfg"]
    soil = traj.position[:, traj.species == shear.SOIL]
    length, width, _ = cfg["box"]
    assert soil[..., 1].min() > 0 and soil[..., 1].max() < width
    assert soil[..., 0].min() > 0 and soil[..., 0].max() < length + tiny["row"]["displacement"]
    assert soil[..., 2].min() > 0


def test_modulus_is_a_log_scaled_property_and_time_step_follows_it(tiny):
    traj, row = tiny["traj"], tiny["row"]
    assert traj.property_names == ("young", "normal_stress")
    np.testing.assert_allclose(traj.properties[:, 0], row["young"], rtol=1e-6)
    np.testing.assert_allclose(traj.properties[:, 1], row["normal_stress"], rtol=1e-6)
    assert traj.parameters["log_scaled_properties"] == ["young", "normal_stress"]
    dt, limit, _ = shear.dem_step(row, "test")
    assert traj.parameters["dem_time_step"] == pytest.approx(dt) and dt < limit
    softer = dict(row, young=row["young"] / 100)
    assert shear.dem_step(softer, "test")[0] == pytest.approx(10 * dt)        # dt ~ 1/sqrt(E)


def test_mdanalysis_opens_the_real_sim_with_our_numbers(tiny):
    """The 3D sim as MDAnalysis reads it (docs/data.md): every frame's positions, box edges and time, in m and s."""
    pytest.importorskip("MDAnalysis")
    from generators import h5md_mdanalysis

    traj = tiny["traj"]
    u = h5md_mdanalysis.universe(tiny["path"])
    assert (u.trajectory.n_frames, u.atoms.n_atoms) == traj.position.shape[:2]
    for i, ts in enumerate(u.trajectory):
        np.testing.assert_array_equal(ts.positions, traj.position[i])
        np.testing.assert_allclose(ts.dimensions, [*(traj.box_upper - traj.box_lower), 90, 90, 90], rtol=1e-7)
        assert ts.time == pytest.approx(traj.time[i], rel=1e-12) and ts.data["step"] == traj.step[i]
    np.testing.assert_array_equal(u.atoms.types, traj.species.astype(str))


def test_yade_left_no_server_open(tiny):
    assert tiny["meta"].run.notes["servers_closed"] == 0            # never started (runner.LAUNCH)
    assert tiny["meta"].run.notes["listening_sockets"] == []


def test_a_pour_that_settles_below_the_box_height_is_refused(tiny):
    packing, cfg = tiny["packing"], tiny["cfg"]
    settled_high = dem.Particles(packing.x + np.array([0.0, 0.0, cfg["box"][2]]), packing.radius,
                                 packing.species, packing.groups)
    shear.check_filled(settled_high, cfg, "packing p")                          # reaches above H: accepted
    with pytest.raises(ValueError, match=r"packing p: the settled soil reaches z = .* below the box height"):
        shear.check_filled(packing.subset(packing.x[:, 2] < 0.5 * cfg["box"][2]), cfg, "packing p")


def test_two_threads_run_the_same_shear_test(tiny, tmp_path):
    """YADE's own threads (-j 2, the benchmark's 2-core contender): the same sim, recorded as run on 2
    threads. The parallel force sums round differently (the summation order differs), and under the
    platen's load that round-off grows through the contact network as any perturbation does (the DEM's
    chaos, docs/surrogate.md): measured 1.1e-3 of the soil's motion at the last frame (7.0 um of 6.3 mm), so
    the positions must agree to 1 % of it."""
    meta = engine.simulate(shear.SCENE, tiny["row"], tiny["meta"].packing, tmp_path / "raw", threads=2)
    assert meta.run.threads == 2 and " -j 2 " in meta.run.command
    assert meta.run.window_seconds > 0 and meta.run.runup_seconds is not None
    two = convert.trajectory(tmp_path / "raw")
    soil = two.species == shear.SOIL
    motion = np.abs(tiny["traj"].position[-1, soil] - tiny["traj"].position[0, soil]).max()
    difference = np.abs(two.position[:, soil] - tiny["traj"].position[:, soil]).max()
    assert difference < 1e-2 * motion
    box = two.species == shear.BOX
    assert np.array_equal(two.position[:, box], tiny["traj"].position[:, box])
    platen = two.species == shear.PLATEN      # moved by its summed contact forces: round-off as the soil
    assert np.abs(two.position[:, platen] - tiny["traj"].position[:, platen]).max() < 1e-2 * motion
