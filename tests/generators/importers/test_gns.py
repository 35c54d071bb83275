"""GNS .npz import: a dataset folder written as GNS writes it (entries of (positions, particle_type) and the
gns_data layout, metadata.json) read back from H5MD number for number; the refusals (no radius, a pickle that
would run a command, wrong dimensions, a corrupt file, a disagreeing time step)."""

import hashlib
import json
import re

import numpy as np
import pytest

from generators import h5md
from generators.importers import gns
from generators.importers.metadata import Given, ImportRefused
from generators.solidgn import safe_pickle
from graphdem import cli

META = {"bounds": [[0.1, 0.9], [0.05, 0.95]], "dt": 0.0025, "dim": 2, "default_connectivity_radius": 0.015,
        "sequence_length": 4, "vel_mean": [0.0, -0.001], "vel_std": [0.002, 0.003], "acc_mean": [0.0, 0.0],
        "acc_std": [1e-4, 1e-4]}
TYPES = np.array([5, 6, 3, 6])          # water, sand, a kinematic boundary particle (type 3), sand


def positions(seed: int, frames: int = 5) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0.1, 0.9, (frames, len(TYPES), 2))


def pair(*items) -> np.ndarray:
    """What ``np.savez(path, key=(positions, particle_type))`` stored on numpy < 1.24: an object array of the two
    (numpy 2 refuses the ragged tuple, so it is built as that numpy built it)."""
    out = np.empty(len(items), dtype=object)
    out[:] = list(items)
    return out


def gns_folder(root):
    """train.npz as GNS's converters write it (one entry per trajectory), valid.npz as its current converter does
    (gns_data: an object array of tuples), and metadata.json."""
    root.mkdir()
    np.savez_compressed(root / "train.npz", simulation_trajectory_0=pair(positions(0), TYPES),
                        simulation_trajectory_1=pair(positions(1), TYPES))
    data = np.empty(1, dtype=object)
    data[0] = (positions(2), TYPES)
    np.savez_compressed(root / "valid.npz", gns_data=data)
    (root / "metadata.json").write_text(json.dumps(META))
    return root


def run(*argv) -> int:
    return cli.main(["import", *map(str, argv)])


def test_a_gns_dataset_round_trips_with_the_given_radius_and_density(tmp_path):
    src = gns_folder(tmp_path / "WaterDrop")
    out = tmp_path / "out"
    assert run("gns", src, out, "--radius", "5=0.004", "--radius", "6=0.005", "--radius", "3=0.004",
               "--density", "1000", "--dt", "0.0025") == 0          # a --dt that agrees with the metadata
    table = (out / "splits.csv").read_text().splitlines()
    assert table == ["id,split,path,source", f"WaterDrop_0000,train,{out}/WaterDrop_0000.h5,{src}/train.npz: "
                     "simulation_trajectory_0", f"WaterDrop_0001,train,{out}/WaterDrop_0001.h5,{src}/train.npz: "
                     "simulation_trajectory_1", f"WaterDrop_0002,valid,{out}/WaterDrop_0002.h5,{src}/valid.npz: "
                     "gns_data[0]"]
    for i, file in enumerate(("train.npz", "train.npz", "valid.npz")):
        traj = h5md.read(out / f"WaterDrop_{i:04d}.h5")
        np.testing.assert_array_equal(traj.position, positions(i).astype(np.float32))
        np.testing.assert_array_equal(traj.species, TYPES)
        radius = np.array([0.004, 0.005, 0.004, 0.005])
        np.testing.assert_array_equal(traj.radius, radius.astype(np.float32))
        np.testing.assert_array_equal(traj.mass, (1000 * np.pi * radius**2).astype(np.float32))   # a disc, 1 m thick
        np.testing.assert_array_equal(traj.kinematic, [False, False, True, False])               # GNS: type 3
        np.testing.assert_array_equal(traj.time, np.arange(5) * 0.0025)
        np.testing.assert_array_equal(traj.step, np.arange(5))
        np.testing.assert_array_equal(traj.box_lower, [0.1, 0.05])
        np.testing.assert_array_equal(traj.box_upper, [0.9, 0.95])
        assert traj.boundary == ("none", "none")
        p = traj.parameters
        assert p["source_format"] == "gns" and p["source_file"] == str((src / file).resolve())
        assert p["source_sha256"] == hashlib.sha256((src / file).read_bytes()).hexdigest()
        assert p["scene"] == p["dataset"] == "WaterDrop" and p["connectivity_radius"] == 0.015
        assert p["source_metadata"] == META and p["kinematic_types"] == [3]
        assert p["importer_options"]["items"]["density"] == {"value": 1000.0, "from": "--density"}
    record = json.loads((out / "import.json").read_text())
    assert record["sims"] == 3 and record["format"] == "gns" and len(record["files"]) == 2


def test_a_plain_npz_and_a_metadata_file_give_what_the_source_lacks(tmp_path):
    """An .npz of plain arrays (no pickle) and a YAML file with the box, time step, kinematic types and masses;
    a GNS 3-tuple's material property becomes a per-particle property."""
    src = tmp_path / "one.npz"
    np.savez(src, positions=positions(3, frames=3), particle_type=TYPES)
    meta = tmp_path / "meta.yaml"
    meta.write_text("radius: 0.01\nmass: {5: 0.2, 6: 0.3}\nkinematic_types: [3, 6]\nbox: [[0, 1], [0, 2]]\n"
                    "frame_interval: 0.1\n")
    assert run("gns", src, tmp_path / "out", "--meta", meta) == 0
    traj = h5md.read(tmp_path / "out" / "one_0000.h5")
    np.testing.assert_array_equal(traj.position, positions(3, frames=3).astype(np.float32))
    np.testing.assert_array_equal(traj.mass, np.array([0.2, 0.3, 0.0, 0.3], np.float32))  # kinematic 3: 0
    np.testing.assert_array_equal(traj.kinematic, [False, True, True, True])      # the given types, not GNS's
    np.testing.assert_array_equal(traj.time, [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(traj.box_upper, [1.0, 2.0])
    assert not (tmp_path / "out" / "splits.csv").exists()          # one file: no splits
    as_dict = tmp_path / "dict.npz"             # a dict per trajectory, one particle type for all (a number)
    np.savez(as_dict, simulation_trajectory_0=np.array({"positions": positions(5), "particle_type": 6}, dtype=object))
    (_, source), = gns.sources(as_dict, Given())
    np.testing.assert_array_equal(source.position, positions(5))
    np.testing.assert_array_equal(source.species, [6, 6, 6, 6])
    triple = tmp_path / "triple.npz"
    np.savez(triple, simulation_trajectory_0=pair(positions(4), TYPES, np.float64(30.0)))
    (_, source), = gns.sources(triple, Given())
    np.testing.assert_array_equal(source.properties[:, 0], [30.0] * 4)
    assert source.property_names == ("material_property",)


def test_a_pickle_that_would_run_a_command_is_refused_by_name(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)

    class RunsACommand:
        def __reduce__(self):
            import os
            return (os.system, ("touch PWNED_BY_PICKLE",))

    src = tmp_path / "bad.npz"
    np.savez(src, simulation_trajectory_0=pair(RunsACommand(), TYPES))
    with pytest.raises(safe_pickle.UnsafePickle, match=r"bad.npz: simulation_trajectory_0: refused to load "
                                                       r"posix.system"):
        list(gns.sources(src, Given()))
    assert run("gns", src, tmp_path / "out", "--radius", "0.01", "--mass", "1", "--dt", "0.1") == 1
    err = capsys.readouterr().err
    assert "refused to load posix.system" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "PWNED_BY_PICKLE").exists() and not (tmp_path / "out").exists()


@pytest.mark.parametrize("meta, message", [
    ({}, "no particle radius .*: give --radius or the key 'radius' of a metadata file"),
    ({"radius": 0.01}, "no particle mass .*give --mass .* or --density"),
    ({"radius": 0.01, "mass": 1.0, "dim": 3}, "positions have 2 coordinates per particle, but .* says dim 3"),
    ({"radius": {5: 0.01}, "mass": 1.0},
     r"key 'radius': no radius for particle type\(s\) \[3, 6\] \(given for \[5\]\)"),
])
def test_a_missing_item_or_a_wrong_dimension_is_refused_in_one_line(tmp_path, capsys, meta, message):
    src = gns_folder(tmp_path / "src")
    path = tmp_path / "meta.json"
    path.write_text(json.dumps(meta))
    assert run("gns", src, tmp_path / "out", "--meta", path) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("graphdem import: error: ")
    assert re.search(message, err), err
    assert not (tmp_path / "out").exists()


def test_wrong_shapes_non_finite_positions_a_corrupt_file_and_a_disagreeing_dt_are_refused(tmp_path):
    items = Given({"radius": 0.01, "mass": 1.0, "dt": 0.1, "box": [[0, 1], [0, 1]]}, {})
    cases = {"flat.npz": pair(positions(0)[:, :, 0], TYPES), "nan.npz": pair(np.where(
        np.arange(20).reshape(5, 4, 1) == 9, np.nan, positions(0)), TYPES), "types.npz": pair(positions(0), TYPES[:3])}
    for name, entry in cases.items():
        np.savez(tmp_path / name, simulation_trajectory_0=entry)
    from generators.importers import sims

    def imported(name):
        return [sims.trajectory(s, items, {}) for _, s in gns.sources(tmp_path / name, items)]
    with pytest.raises(ImportRefused, match=r"flat.npz: simulation_trajectory_0: positions must be an array "
                                            r"\[T, N, D\], got ndarray of shape \(5, 4\)"):
        imported("flat.npz")
    with pytest.raises(h5md.H5MDError, match="nan.npz: simulation_trajectory_0: non-finite position at frame 2, "
                                             "particle 1"):
        imported("nan.npz")
    with pytest.raises(ImportRefused, match=r"particle_type must be one number or 4 \(one per particle\), got "
                                            r"shape \(3,\)"):
        imported("types.npz")
    (tmp_path / "cut.npz").write_bytes((tmp_path / "types.npz").read_bytes()[:100])
    with pytest.raises(ImportRefused, match="cut.npz: not a readable .npz file"):
        imported("cut.npz")
    src = gns_folder(tmp_path / "src")
    with pytest.raises(ImportRefused, match=r"dt = 0.0025 s per frame\) gives the frame times and --dt "
                                            r"another \(0.0025 against 0.1 at entry 1\)"):
        [sims.trajectory(s, Given({"radius": 0.01, "mass": 1.0, "dt": 0.1}, {"dt": "--dt"}), {})
         for _, s in gns.sources(src, items)]
