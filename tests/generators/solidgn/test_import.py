"""Solid-GN import: a safe unpickler, shape and finiteness checks, and a real file converted."""

import json
import pickle
from pathlib import Path

import numpy as np
import pytest

from generators import h5md
from generators.solidgn import convert, safe_pickle
from graphdem import cli

SOURCE = Path(__file__).resolve().parents[4] / "shared" / "datasets" / "solidgn"


class RunsACommand:
    def __reduce__(self):
        import os
        return (os.system, ("touch PWNED_BY_PICKLE",))


def fake_dataset(root: Path, trajectories: dict[str, object]) -> Path:
    (root / "train").mkdir(parents=True)
    (root / "metadata.json").write_text(json.dumps({"bounds": [[0, 100], [0, 80]], "dim": 2, "dt": 0.001,
                                                    "default_connectivity_radius": 9.75}))
    for name, obj in trajectories.items():
        (root / "train" / f"{name}.pkl").write_bytes(pickle.dumps(obj))
    return root


def good(n=5, frames=4):
    rng = np.random.default_rng(0)
    return {"particle_type": np.array([0.0, 0, 1, 1, 2])[:n], "particle_r": np.full(n, 1.5),
            "particle_m": np.array([0.0, 0, 5, 5, 5])[:n], "position": rng.uniform(0, 80, (frames, n, 2)),
            "heat": np.zeros((frames, n, 4))}


def test_a_pickle_that_would_run_a_command_is_refused_and_runs_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    src = fake_dataset(tmp_path / "src", {"0": {"position": RunsACommand()}})
    with pytest.raises(safe_pickle.UnsafePickle, match=r"0.pkl: refused to load posix.system"):
        convert.import_dataset(src, tmp_path / "dest", progress=False)
    assert not (tmp_path / "PWNED_BY_PICKLE").exists()
    assert cli.main(["import-solidgn", str(src), str(tmp_path / "dest"), "--no-progress"]) == 1
    assert not (tmp_path / "PWNED_BY_PICKLE").exists() and not (tmp_path / "dest" / "splits.csv").exists()


@pytest.mark.parametrize("change, message", [
    ({"position": np.zeros((4, 5))}, "position must be a 3-dimensional numpy array"),
    ({"particle_r": np.full(4, 1.5)}, "particle_type/r/m have 5/4/5 entries"),
    ({"position": np.full((4, 5, 2), np.nan)}, "position has non-finite values"),
    ({"particle_type": np.array([0, 0, 1, 1.5, 2])}, "particle_type must hold non-negative integers"),
])
def test_wrong_shaped_or_non_finite_arrays_are_rejected_naming_the_file(tmp_path, change, message):
    src = fake_dataset(tmp_path / "src", {"7": {**good(), **change}})
    with pytest.raises(ValueError, match=rf"train/7.pkl: .*{message}"):
        convert.import_dataset(src, tmp_path / "dest", progress=False)


def test_walls_are_kinematic_and_radii_are_kept(tmp_path):
    src = fake_dataset(tmp_path / "src", {"0": good(), "1": good()})
    table = convert.import_dataset(src, tmp_path / "dest", progress=False)
    assert list(table["id"]) == ["train_0", "train_1"]
    traj = h5md.read(tmp_path / "dest" / "sims" / "train_0.h5")
    np.testing.assert_array_equal(traj.kinematic, [True, True, False, False, False])
    np.testing.assert_allclose(traj.position, good()["position"].astype(np.float32))
    assert traj.parameters["scene"] == "solidgn" and traj.box_upper.tolist() == [100.0, 80.0]


def test_limits_keep_the_first_trajectories_by_number(tmp_path):
    src = fake_dataset(tmp_path / "src", {str(i): good() for i in (0, 1, 2, 10)})
    table = convert.import_dataset(src, tmp_path / "dest", progress=False, limits={"train": 3})
    assert list(table["id"]) == ["train_0", "train_1", "train_2"]          # numeric order, not 0, 1, 10
    with pytest.raises(ValueError, match=r"unknown splits \['tset'\]"):
        convert.import_dataset(src, tmp_path / "dest", progress=False, limits={"tset": 1})


@pytest.mark.skipif(not SOURCE.is_dir(), reason="the Solid-GN data is not beside this checkout")
def test_a_real_slide_small_trajectory_converts(tmp_path):
    traj = convert.trajectory(SOURCE / "Slide" / "train" / "0.pkl",
                              json.loads((SOURCE / "Slide" / "metadata.json").read_text()), "Slide")
    assert traj.n_frames == 20 and traj.dim == 2
    moving = ~traj.kinematic
    assert 28 <= moving.sum() <= 41 and len(np.unique(traj.radius[moving])) > 1     # heterogeneous radii
    assert np.all(traj.mass[moving] > 0)
