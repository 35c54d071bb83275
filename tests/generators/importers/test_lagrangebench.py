"""LagrangeBench import: a dataset folder written as LagrangeBench's converters write it (one h5 per split, a group
per trajectory with position and particle_type; metadata.json) read back number for number; the refusals."""

import json

import h5py
import numpy as np
import pandas as pd
import pytest

import graphdem
from generators.importers import lagrangebench, sims
from generators.importers.metadata import Given, ImportRefused
from graphdem import cli
from surrogate import dataset

META = {"case": "DAM", "solver": "SPH", "dim": 2, "dx": 0.02, "dt": 0.0003, "write_every": 100,
        "bounds": [[0.0, 5.486], [0.0, 2.12]], "periodic_boundary_conditions": [True, False, True],
        "default_connectivity_radius": 0.029, "num_particles_max": 6, "sequence_length_train": 4,
        "vel_mean": [0.0, 0.0], "vel_std": [0.1, 0.1]}
TYPES = np.array([0, 0, 0, 1, 1, 2])    # fluid, fluid, fluid, solid wall, solid wall, moving wall


def position(seed: int, frames: int = 4) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0.1, 2.0, (frames, len(TYPES), 2)).astype(np.float32)


def lb_folder(root, splits=(("train", 2), ("valid", 1))):
    root.mkdir()
    seed = 0
    for split, count in splits:
        with h5py.File(root / f"{split}.h5", "w") as f:
            for key in range(count):
                group = f.create_group(str(key).zfill(5))
                group.create_dataset("particle_type", data=TYPES)
                group.create_dataset("position", data=position(seed))
                seed += 1
    (root / "metadata.json").write_text(json.dumps(META))
    return root


def test_a_lagrangebench_dataset_round_trips(tmp_path):
    src = lb_folder(tmp_path / "2D_DAM_5740_20kevery100")
    out = tmp_path / "out"
    assert cli.main(["import", "lagrangebench", str(src), str(out), "--radius", "0.01", "--mass", "0=0.4",
                     "--name", "dam"]) == 0
    rows = (out / "splits.csv").read_text().splitlines()[1:]
    assert [r.split(",")[:2] for r in rows] == [["dam_0000", "train"], ["dam_0001", "train"], ["dam_0002", "valid"]]
    for i in range(3):
        traj = graphdem.load_sim(out / f"dam_{i:04d}.h5")
        np.testing.assert_array_equal(traj.position, position(i))
        np.testing.assert_array_equal(traj.species, TYPES)
        np.testing.assert_array_equal(traj.radius, np.full(6, 0.01, np.float32))
        np.testing.assert_array_equal(traj.mass, np.array([0.4, 0.4, 0.4, 0, 0, 0], np.float32))   # walls: 0
        np.testing.assert_array_equal(traj.kinematic, [False, False, False, True, True, True])   # types 1, 2
        np.testing.assert_array_equal(traj.step, [0, 100, 200, 300])                           # write_every
        np.testing.assert_array_equal(traj.time, np.array([0, 100, 200, 300]) * 0.0003)
        np.testing.assert_array_equal(traj.box_lower, [0.0, 0.0])
        np.testing.assert_array_equal(traj.box_upper, [5.486, 2.12])
        assert traj.boundary == ("periodic", "none")
        p = traj.parameters
        assert p["source_format"] == "lagrangebench" and p["source_entry"].endswith(("00000", "00001"))
        assert p["species_names"]["2"] == "moving wall" and p["connectivity_radius"] == 0.029
        assert p["frame_interval"] == pytest.approx(0.03)
    stats = dataset.build(pd.read_csv(out / "splits.csv"), tmp_path / "dataset", 0.029)   # graphdem dataset --table
    assert stats["splits"] == {"train": 2, "valid": 1} and stats["scene"] == "dam" and stats["dim"] == 2


def test_a_missing_dataset_a_wrong_dimension_and_a_corrupt_file_are_refused(tmp_path):
    items = Given({"radius": 0.01, "mass": 1.0})
    src = lb_folder(tmp_path / "src", splits=(("train", 1),))
    with h5py.File(src / "train.h5", "a") as f:
        del f["00000/particle_type"]
    with pytest.raises(ImportRefused, match="train.h5: missing 00000/particle_type; a LagrangeBench trajectory"):
        list(lagrangebench.sources(src, items))
    wide = tmp_path / "wide.h5"
    with h5py.File(wide, "w") as f:
        f.create_dataset("00000/position", data=np.zeros((3, 6, 4)))
        f.create_dataset("00000/particle_type", data=TYPES)
    (_, source), = lagrangebench.sources(wide, items)
    with pytest.raises(ImportRefused, match=r"wide.h5: 00000: positions must be numbers of shape \[T, N, D\] with "
                                            r"at least 2 frames, 1 particle and D 2 or 3, got ndarray float64 "
                                            r"\(3, 6, 4\)"):
        sims.trajectory(source, items, {})
    (tmp_path / "cut.h5").write_bytes(wide.read_bytes()[:500])
    with pytest.raises(ImportRefused, match="cut.h5: not a readable HDF5 file"):
        list(lagrangebench.sources(tmp_path / "cut.h5", items))
    (src / "metadata.json").write_text(json.dumps({**META, "dim": 3}))
    with h5py.File(src / "train.h5", "a") as f:
        f["00000/particle_type"] = TYPES
    with pytest.raises(ImportRefused, match=r"train.h5: 00000: positions have 2 coordinates per particle, but "
                                            r".*metadata.json says dim 3"):
        list(lagrangebench.sources(src, items))
