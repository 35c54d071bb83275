"""LAMMPS under MPI: a real 2-rank run of a tiny meteorite (ci scale) against the serial run of the same row
from the same packing, and the refusals.

A run on 2 ranks is not bitwise equal to the serial one: each rank sums the contact forces of its own atoms
and of its ghost copies in its own order, so the sums differ in the last bits, and DEM is chaotic, so the
difference grows. Measured on this scene (frames 0-29, 135 DEM steps per frame, dumps at 17 significant
digits): no difference at all up to frame 12, then 4e-15 m at frame 13, 1e-13 m at frame 22 and 6e-13 m
(8e-14 radii) at frame 29; the recorded data (10 significant digits in the dumps, float32 in H5MD) do not
see it. The tolerances below leave a factor of about 10^4 over those figures for other compilers and CPUs,
and are still far below anything physical. (At the paper scale the difference reaches the recorded digits
after about 16 frames and a radius by the end of the window: docs/architecture.md, "LAMMPS under MPI".)
"""

import re

import numpy as np
import pytest

from generators import blowup, config, convert, dem, engine, h5md, sweep
from generators.lammps import driver, runner
from generators.scenes import meteorite
from generators.yade import driver as yade_driver

FRAMES = 30
ROUND_OFF = 1e-9          # radii: the full-precision tolerance (measured at most 8e-14 radii over the window)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The first sweep row of a tiny meteorite on 1 and on 2 ranks from one serial packing: the recorded
    H5MD files and raw folders, and the positions of a second pair of runs dumped at 17 digits."""
    cfg = config.load({"scale": "ci", "meteorite": {"bed_depth": 30.0, "frames": FRAMES}})["meteorite"]
    root = tmp_path_factory.mktemp("mpi")
    engine.prepare(meteorite.SCENE, "lammps", meteorite.SCENE.packings(cfg)[0], root / "packing")
    row = sweep.build("meteorite", cfg).iloc[0].to_dict()
    out = {"records": {}, "traj": {}, "raw": {}, "full": {}, "row": row, "packing": root / "packing"}
    for ranks in (1, 2):
        rec = engine.simulate(meteorite.SCENE, row, root / "packing", root / f"raw{ranks}", ranks=ranks)
        out["records"][ranks] = rec
        out["raw"][ranks] = root / f"raw{ranks}"
        out["traj"][ranks] = h5md.read(convert.convert(root / f"raw{ranks}", root / f"sim{ranks}.h5"))
    serial_run = runner.run
    with pytest.MonkeyPatch.context() as mp:       # the same decks, dumping 17 significant digits
        mp.setattr(runner, "run", lambda text, *a, **k: serial_run(text.replace("%.10g", "%.17g"), *a, **k))
        for ranks in (1, 2):
            rec = engine.simulate(meteorite.SCENE, row, root / "packing", root / f"full{ranks}", ranks=ranks)
            out["full"][ranks] = driver.read_raw(root / f"full{ranks}", rec.dt)
    return out


@pytest.mark.engine
def test_the_two_rank_run_is_recorded_as_such(runs):
    serial, parallel = runs["records"][1].run, runs["records"][2].run
    assert serial.ranks == 1 and "mpirun" not in serial.command
    assert parallel.ranks == 2 and parallel.command.split()[0].endswith("unshare")     # mpirun in a namespace
    assert f" {runner.mpirun_path()} --allow-run-as-root -np 2" in parallel.command
    assert "-np 2 --host localhost:2" in parallel.command and "--mca btl self,vader" in parallel.command
    assert runs["traj"][1].parameters["engine_ranks"] == 1 and runs["traj"][2].parameters["engine_ranks"] == 2
    log = (runs["raw"][2] / "log.lammps").read_text()
    assert re.search(r"^\s*2 by 1 by 1 MPI processor grid", log, re.M)        # split along x: 2 slabs of the bed
    assert runner.ranks_of(runs["raw"][2] / "log.lammps") == 2
    assert parallel.steps == serial.steps and parallel.window_seconds > 0


@pytest.mark.engine
def test_same_particles_ids_and_species_on_two_ranks(runs):
    one, two = runs["traj"][1], runs["traj"][2]
    assert one.position.shape == two.position.shape == (FRAMES, one.n_particles, 2)
    for field in ("species", "radius", "mass", "kinematic", "step", "time"):
        np.testing.assert_array_equal(getattr(one, field), getattr(two, field), err_msg=field)
    ids = [driver.io.read_dump(runs["raw"][r] / "static.dump")[0][1]["id"].to_numpy() for r in (1, 2)]
    np.testing.assert_array_equal(ids[0], ids[1])
    np.testing.assert_array_equal(ids[0], np.arange(1, one.n_particles + 1))
    for r in (1, 2):            # every frame of the dump lists every particle, whichever rank wrote it
        frames = driver.io.read_dump(runs["raw"][r] / "frames.dump")
        assert all(np.array_equal(t["id"].to_numpy(), ids[0]) for _, t in frames)


@pytest.mark.engine
def test_the_recorded_positions_agree_to_the_last_printed_digit(runs):
    """The dumps hold 10 significant digits: the two runs differ by at most one unit of the last one, and the
    float32 H5MD positions by at most one float32 step."""
    a, b = (driver.read_raw(runs["raw"][r], runs["records"][r].dt)["position"] for r in (1, 2))
    last_digit = 10.0 ** (np.floor(np.log10(np.maximum(np.abs(a), 1e-30))) - 9)
    assert np.all(np.abs(a - b) <= last_digit * 1.0001)
    one, two = (np.asarray(runs["traj"][r].position) for r in (1, 2))
    assert np.all(np.abs(one.astype(float) - two.astype(float)) <= np.spacing(np.abs(one)).astype(float))


@pytest.mark.engine
def test_at_full_precision_they_differ_by_round_off_only(runs):
    """At 17 digits the two runs differ by the engine's parallel round-off alone: below 1e-9 radii in every
    frame of the window (measured: at most 8e-14 radii; 0 in the first 13 frames)."""
    a, b = runs["full"][1], runs["full"][2]
    np.testing.assert_array_equal(a["species"], b["species"])
    distance = np.linalg.norm(a["position"] - b["position"], axis=-1) / a["radius"]
    assert distance.shape == (FRAMES, len(a["radius"]))
    assert distance.max() < ROUND_OFF, distance.max(axis=1)
    # the meteorite strikes the bed within the window: the comparison covers contacts, not a free flight
    moved = np.linalg.norm(a["position"][-1] - a["position"][0], axis=-1)
    assert (moved[a["species"] == meteorite.GROUND] > 0.1 * a["radius"].min()).any()


@pytest.mark.engine
def test_a_blow_up_on_two_ranks_is_named_as_on_one(runs, tmp_path):
    row = {**runs["row"], "dt": None, "dt_safety": 4.0}           # 200 x the scene's step: particles fly off
    causes = []
    for ranks in (1, 2):
        with pytest.raises(blowup.BlowUp, match="particles left the domain") as err:
            engine.simulate(meteorite.SCENE, row, runs["packing"], tmp_path / f"raw{ranks}", ranks=ranks)
        causes.append(str(err.value))
    assert causes[0] == causes[1]


@pytest.mark.engine
def test_an_lmp_of_another_mpi_is_refused(runs, tmp_path, monkeypatch):
    """A launcher that starts one serial copy (as mpirun starts N of an lmp built without its MPI): the log
    says 1 rank, 2 were asked for."""
    fake = tmp_path / "fake-mpirun"
    fake.write_text('#!/bin/sh\nwhile [ "${1##*/}" != lmp ]; do shift; done\nexec "$@"\n')
    fake.chmod(0o755)
    monkeypatch.setenv(runner.MPIRUN_ENV, str(fake))
    with pytest.raises(runner.MpiMismatch, match=r"LAMMPS ran on 1 MPI rank\(s\), 2 asked for"):
        engine.simulate(meteorite.SCENE, runs["row"], runs["packing"], tmp_path / "raw", ranks=2)


@pytest.mark.engine
def test_a_3d_shear_box_with_moving_walls_on_two_ranks(tmp_path):
    """The shear box in LAMMPS (3D, its walls kinematic particles moved by `fix move`, split between the
    ranks): the same particles, the box walls where the serial run puts them bit for bit, the soil and the
    load platen (moved by its forces, summed over the ranks in another order) within 1e-9 of the box's length: the
    rounding of the sums grows with the granular chaos (2e-11 m, 2e-10 of the length, by the 5th frame of the
    flanged box)."""
    from generators.scenes import shear
    cfg = config.load({"scale": "ci", "shear": {"radius": [0.008, 0.01], "wall_radius": 0.008,
                                                "frames": 6, "model": {"history": 5}}})["shear"]
    engine.prepare(shear.SCENE, "lammps", shear.SCENE.packings(cfg)[0], tmp_path / "packing")
    row = {**sweep.build("shear", cfg).iloc[0].to_dict(), "engine": "lammps"}
    raw = {}
    for ranks in (1, 2):
        rec = engine.simulate(shear.SCENE, row, tmp_path / "packing", tmp_path / f"raw{ranks}", ranks=ranks)
        assert rec.run.ranks == ranks
        raw[ranks] = driver.read_raw(tmp_path / f"raw{ranks}", rec.dt)
    a, b = raw[1], raw[2]
    assert a["position"].shape == b["position"].shape and a["position"].shape[2] == 3
    np.testing.assert_array_equal(a["species"], b["species"])
    walls = a["species"] == shear.BOX
    assert np.abs(a["position"][-1, walls] - a["position"][0, walls]).max() > 0        # the walls did move
    np.testing.assert_array_equal(a["position"][:, walls], b["position"][:, walls])
    assert np.abs(a["position"] - b["position"]).max() <= 1e-9 * max(cfg["box"])


def test_the_serial_command_is_lmp_alone():
    assert runner.command(1)[0].endswith("lmp") and len(runner.command(1)) == 3


def test_more_ranks_without_mpirun_are_refused_by_key(monkeypatch):
    monkeypatch.setenv(runner.MPIRUN_ENV, "no-such-mpirun")
    with pytest.raises(config.ConfigError, match=r"config key 'meteorite.ranks' = 2 runs LAMMPS under "
                                                 r"`mpirun -np 2`, and mpirun is not on PATH.*allowed without it: 1"):
        config.load({"scale": "ci", "meteorite": {"ranks": 2}})
    assert config.load({"scale": "ci", "meteorite": {"ranks": 1}})["meteorite"]["ranks"] == 1
    with pytest.raises(runner.MpiUnavailable, match="allowed without it: ranks = 1"):
        runner.command(2)


def test_more_ranks_where_mpirun_cannot_have_a_network_namespace_are_refused_by_key(monkeypatch):
    """mpirun listens on every address: where it cannot run in a namespace of its own (a container that refuses
    user namespaces), more than one rank is refused when the config is read, and by the runner."""
    monkeypatch.setattr(runner.netns, "problem", lambda: "unshare: Operation not permitted")
    with pytest.raises(config.ConfigError, match=r"config key 'meteorite.ranks' = 2 runs LAMMPS under `mpirun -np 2` "
                                                 r"in a network namespace of its own .*\(unshare: Operation not "
                                                 r"permitted; .*allowed here: 1$"):
        config.load({"scale": "ci", "meteorite": {"ranks": 2}})
    assert runner.command(1)[0].endswith("lmp")
    with pytest.raises(runner.MpiUnisolated, match=r"^ranks = 2 runs LAMMPS under .*allowed here: 1$"):
        runner.command(2)


@pytest.mark.parametrize("ranks", [0, 1.5, "two"])
def test_ranks_must_be_a_positive_whole_number(ranks):
    with pytest.raises(config.ConfigError, match=r"'meteorite.ranks'"):
        config.load({"scale": "ci", "meteorite": {"ranks": ranks}})
    with pytest.raises(ValueError, match="positive number of MPI ranks"):
        runner.command(ranks)


def test_yade_runs_refuse_more_than_one_rank(tmp_path):
    cfg = config.load({"scale": "ci"})["meteorite"]
    setup = meteorite.SCENE.settle_setup(meteorite.SCENE.packings(cfg)[0])
    for run in (yade_driver.settle, yade_driver.run_recording):
        with pytest.raises(dem.UnsupportedSetup, match="ranks = 2; YADE runs one process"):
            run(setup, tmp_path, ranks=2)
    assert not any(tmp_path.iterdir())


def test_lammps_runs_refuse_threads(tmp_path):
    """More cores for LAMMPS are MPI ranks; a thread count other than 1 is refused before anything runs."""
    cfg = config.load({"scale": "ci"})["meteorite"]
    setup = meteorite.SCENE.settle_setup(meteorite.SCENE.packings(cfg)[0])
    for run in (driver.settle, driver.run_recording):
        with pytest.raises(dem.UnsupportedSetup, match="threads = 2; LAMMPS runs one thread per MPI rank"):
            run(setup, tmp_path, threads=2)
    assert not any(tmp_path.iterdir())
