"""LAMMPS dump import: a dump of a real (tiny) LAMMPS granular run read back number for number against the
project's own dump reader; a hand-written 3D dump (scaled coordinates, diameters, ITEM: TIME, a shrink-wrapped
box); the refusals."""

import os
import subprocess

import numpy as np
import pytest

from generators import h5md
from generators.importers import lammps_dump, sims
from generators.importers.metadata import Given, ImportRefused
from generators.lammps import io, runner
from graphdem import cli

DECK = """\
units           si
dimension       2
atom_style      sphere
boundary        p f p
region          box block 0 0.1 0 0.1 -0.005 0.005
create_box      2 box
create_atoms    1 single 0.02 0.05 0.0
create_atoms    1 single 0.05 0.06 0.0
create_atoms    2 single 0.08 0.02 0.0
create_atoms    1 single 0.081 0.045 0.0
set             type 1 diameter 0.01
set             type 2 diameter 0.016
set             type 1 density 2500
set             type 2 density 2500
group           wall type 2
pair_style      granular
pair_coeff      * * hooke 1.0e5 0.5 tangential linear_nohistory 1.0 0.5
comm_modify     vel yes
fix             1 all nve/sphere
fix             2 all gravity 9.81 vector 0 -1 0
fix             3 wall setforce 0.0 0.0 0.0
fix             4 all enforce2d
fix             5 all wall/gran granular hooke 1.0e5 0.5 tangential linear_nohistory 1.0 0.5 yplane 0.0 NULL
timestep        1.0e-5
dump            d all custom 500 frames.dump id type x y z radius mass vx vy vz
dump_modify     d format float %.10g
run             4000
"""


@pytest.mark.engine
def test_a_real_lammps_granular_dump_round_trips(tmp_path):
    (tmp_path / "in.lammps").write_text(DECK)
    subprocess.run([*runner.command(1), "-log", "none", "-screen", "none"], cwd=tmp_path, check=True,
                   env={**os.environ, **runner.ENGINE_ENV}, timeout=120)
    (tmp_path / "meta.yaml").write_text("dt: 1.0e-5\nkinematic_types: [2]\n")
    out = tmp_path / "out"
    assert cli.main(["import", "lammps-dump", str(tmp_path / "frames.dump"), str(out),
                     "--meta", str(tmp_path / "meta.yaml")]) == 0
    traj = h5md.read(out / "frames_0000.h5")
    frames = io.read_dump(tmp_path / "frames.dump")           # the project's own reader, sorted by id
    assert len(frames) == 9 and traj.dim == 2                 # z is 0 everywhere: 2D
    np.testing.assert_array_equal(traj.step, [step for step, _ in frames])
    np.testing.assert_array_equal(traj.time, np.array([step for step, _ in frames]) * 1.0e-5)
    np.testing.assert_array_equal(traj.position, np.stack([t[["x", "y"]].to_numpy() for _, t in frames])
                                  .astype(np.float32))
    table = frames[0][1]
    np.testing.assert_array_equal(traj.species, table["type"])
    np.testing.assert_array_equal(traj.radius, table["radius"].to_numpy(np.float32))
    np.testing.assert_array_equal(traj.mass, table["mass"].to_numpy(np.float32))
    np.testing.assert_array_equal(traj.kinematic, [False, False, True, False])
    np.testing.assert_array_equal(traj.box_lower, [0.0, 0.0])
    np.testing.assert_array_equal(traj.box_upper, [0.1, 0.1])
    assert traj.boundary == ("periodic", "none")
    assert np.all(traj.position[:, 2] == traj.position[0, 2])          # the wall particle never moved
    assert np.all(traj.position[-1, [0, 1], 1] < traj.position[0, [0, 1], 1])   # the free grains fell
    assert traj.parameters["dump_columns"][:6] == ["id", "type", "x", "y", "z", "radius"]
    assert traj.parameters["source_format"] == "lammps-dump" and not (out / "splits.csv").exists()


def snapshot(step, time, box, atoms, header="id type xs ys zs diameter", flags="ff ff sm"):
    lines = [f"ITEM: TIMESTEP\n{step}", f"ITEM: TIME\n{time}", f"ITEM: NUMBER OF ATOMS\n{len(atoms)}",
             f"ITEM: BOX BOUNDS {flags}", *(f"{lo} {hi}" for lo, hi in box), f"ITEM: ATOMS {header}",
             *(" ".join(str(v) for v in atom) for atom in atoms)]
    return "\n".join(lines) + "\n"


BOX0 = [(0, 2), (0, 1), (0, 4)]
BOX1 = [(0, 2), (0, 1), (-1, 4)]         # shrink-wrapped z grew downwards


def dump_3d(path):
    path.write_text(snapshot(100, 0.5, BOX0, [(7, 2, 0.5, 0.5, 0.25, 0.2), (3, 1, 0.25, 0.5, 0.5, 0.1)])
                    + snapshot(200, 0.75, BOX1, [(3, 1, 0.25, 0.5, 0.6, 0.1), (7, 2, 0.5, 0.5, 0.2, 0.2)]))
    return path


def test_a_3d_dump_with_scaled_coordinates_times_and_a_shrink_wrapped_box(tmp_path):
    items = Given({"density": {1: 1000.0, 2: 2000.0}}, {"density": "--density"})
    (_, source), = lammps_dump.sources(dump_3d(tmp_path / "grains.dump"), items)
    traj = sims.trajectory(source, items, {})
    np.testing.assert_array_equal(traj.species, [1, 2])                                   # sorted by id: 3, 7
    np.testing.assert_allclose(traj.position, [[[0.5, 0.5, 2.0], [1.0, 0.5, 1.0]],        # lo + s (hi - lo)
                                               [[0.5, 0.5, 2.0], [1.0, 0.5, 0.0]]], rtol=1e-15)
    np.testing.assert_array_equal(traj.radius, [0.05, 0.1])
    np.testing.assert_allclose(traj.mass, [1000 * 4 / 3 * np.pi * 0.05**3, 2000 * 4 / 3 * np.pi * 0.1**3])
    np.testing.assert_array_equal(traj.time, [0.5, 0.75])                                 # ITEM: TIME
    np.testing.assert_array_equal(traj.box_lower, [0, 0, -1])                             # z spans both boxes
    np.testing.assert_array_equal(traj.box_upper, [2, 1, 4])
    assert traj.boundary == ("none",) * 3 and traj.kinematic.sum() == 0
    with pytest.raises(ImportRefused, match=r"grains.dump: its ITEM: TIME gives the frame times and --dt "
                                            r"another \(0.5 against 0.1 at entry 0\)"):
        sims.trajectory(source, Given({**items.values, "dt": 0.001}, {"dt": "--dt"}), {})


@pytest.mark.parametrize("text, message", [
    (snapshot(0, 0, BOX0, [(1, 1, 0.1, 0.1, 0.1, 0.1)], flags="xy xz yz pp pp pp"), "a triclinic box"),
    (snapshot(0, 0, BOX0, [(1, 1, 0.1, 0.1, 0.1, 0.1)]) + snapshot(1, 1, BOX0, [(2, 1, 0.1, 0.1, 0.1, 0.1)]),
     r"step 1 holds other atoms \(1\) than the first snapshot \(1\)"),
    (snapshot(5, 0, BOX0, [(1, 1, 0.1, 0.1, 0.1, 0.1)]) + snapshot(5, 1, BOX0, [(1, 1, 0.1, 0.1, 0.1, 0.1)]),
     "step 5 follows step 5; the steps must increase"),
    (snapshot(0, 0, BOX0, [(1, 1, 0.1, 0.1, 0.1, 0.1)], flags="ff ff ff")
     + snapshot(1, 1, BOX1, [(1, 1, 0.1, 0.1, 0.1, 0.1)], flags="ff ff ff"),
     "the box changes along z \\(flags ff\\)"),
    (snapshot(0, 0, BOX0, [(1, 1, 0.1, 0.1, 0.1, 0.1)], header="id type vx vy vz radius"), "hold no coordinates"),
    (snapshot(0, 0, BOX0, [(1, 1, 0.1, 0.1, 0.1, 0.1)])[:-12], "the 1 atoms of step 0 hold 3 values, not 6"),
    (snapshot(0, 0, BOX0, [(1, 1, 0.1, 0.1, 0.1, 0.1)])[:-20], r"ends inside ATOMS \(truncated\?\)"),
    ("ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n2\n", "ends inside the snapshot of step 0"),
    ("LAMMPS data file\n", "line 1: expected 'ITEM: TIMESTEP'"),
])
def test_a_malformed_dump_is_refused_naming_the_file(tmp_path, text, message):
    path = tmp_path / "bad.dump"
    path.write_text(text)
    with pytest.raises(ImportRefused, match=f"bad.dump: .*{message}"):
        list(lammps_dump.sources(path, Given()))


def test_missing_items_and_a_2d_claim_on_a_3d_dump_are_refused(tmp_path, capsys):
    path = dump_3d(tmp_path / "grains.dump")
    path.write_text(path.read_text().replace("ITEM: TIME\n0.5\n", ""))    # one snapshot without a time
    assert cli.main(["import", "lammps-dump", str(path), str(tmp_path / "out"), "--mass", "1"]) == 1
    assert capsys.readouterr().err.strip().endswith("no frame times (the source holds no time step): give --dt (s "
                                                    "per step) or --frame-interval (s between frames), or the key "
                                                    "'dt' or 'frame_interval' of a metadata file (--meta FILE)")
    assert cli.main(["import", "lammps-dump", str(path), str(tmp_path / "out"), "--dt", "1e-3"]) == 1
    assert "no particle mass (the source holds none): give --mass" in capsys.readouterr().err
    assert cli.main(["import", "lammps-dump", str(path), str(tmp_path / "out"), "--dim", "2", "--mass", "1",
                     "--frame-interval", "0.1"]) == 1
    assert "--dim says dim 2, but z varies from 0 to 2" in capsys.readouterr().err
    assert cli.main(["import", "lammps-dump", str(path), str(tmp_path / "out"), "--mass", "1",
                     "--frame-interval", "0.1"]) == 0
    np.testing.assert_allclose(h5md.read(tmp_path / "out" / "grains_0000.h5").time, [0.1, 0.2])   # 100 steps: 0.1 s
