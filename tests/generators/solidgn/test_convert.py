"""One Solid-GN trajectory as H5MD: frame times from the metadata's dt, walls kinematic, the box from its bounds
and the metadata kept (the whole import, its refusals and limits: tests/generators/solidgn/test_import.py)."""

import json
import pickle

import numpy as np
import pytest

from generators.solidgn import convert

META = {"dim": 2, "bounds": [[0.0, 100.0], [-5.0, 80.0]], "dt": 0.0025, "default_connectivity_radius": 9.75}


def _pickle(path, frames=3):
    position = np.arange(frames * 3 * 2, dtype=np.float64).reshape(frames, 3, 2)
    path.write_bytes(pickle.dumps({"particle_type": np.array([0.0, 1.0, 2.0]), "particle_r": np.array([1.0, 1.5, 2.0]),
                                   "particle_m": np.array([0.0, 5.0, 7.0]), "position": position}))
    return position


def test_a_trajectory_s_times_walls_box_and_metadata(tmp_path):
    position = _pickle(tmp_path / "4.pkl")
    traj = convert.trajectory(tmp_path / "4.pkl", META, "Slide")
    np.testing.assert_allclose(traj.time, [0.0, 0.0025, 0.005])          # frame index x dt
    np.testing.assert_array_equal(traj.step, [0, 1, 2])
    np.testing.assert_array_equal(traj.position, position.astype(np.float32))
    np.testing.assert_array_equal(traj.kinematic, [True, False, False])   # type 0: the fixed wall
    np.testing.assert_array_equal(traj.species, [0, 1, 2])
    np.testing.assert_array_equal(traj.box_lower, [0.0, -5.0])
    np.testing.assert_array_equal(traj.box_upper, [100.0, 80.0])
    p = traj.parameters
    assert p["frame_interval"] == 0.0025 and p["connectivity_radius"] == 9.75 and p["solidgn_metadata"] == META
    assert p["dataset"] == "Slide" and p["source_file"] == str(tmp_path / "4.pkl")


def test_a_one_frame_trajectory_and_a_dimension_other_than_the_metadata_s_are_refused(tmp_path):
    _pickle(tmp_path / "1.pkl", frames=1)
    with pytest.raises(ValueError, match=r"1.pkl: position has shape \(1, 3, 2\); .* at least 2 frames"):
        convert.trajectory(tmp_path / "1.pkl", META, "Slide")
    _pickle(tmp_path / "2.pkl")
    with pytest.raises(ValueError, match="the metadata's dim is 3"):
        convert.trajectory(tmp_path / "2.pkl", {**META, "dim": 3}, "Slide")


def test_metadata_is_read_checked(tmp_path):
    path = tmp_path / "metadata.json"
    path.write_text(json.dumps(META))
    assert convert.read_metadata(path) == META
    path.write_text(json.dumps({**META, "default_connectivity_radius": 0}))
    with pytest.raises(ValueError, match="'default_connectivity_radius' must be a positive number, got 0"):
        convert.read_metadata(path)
    path.write_text(json.dumps({**META, "bounds": [[0, 1]]}))
    with pytest.raises(ValueError, match="'bounds' must be 2 finite"):
        convert.read_metadata(path)
