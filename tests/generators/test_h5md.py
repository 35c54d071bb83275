import h5py
import numpy as np
import pytest

from generators import h5md


def make_traj(t=5, n=4, d=2) -> h5md.Trajectory:
    rng = np.random.default_rng(0)
    return h5md.Trajectory(
        position=rng.uniform(0, 10, (t, n, d)).astype(np.float32),
        time=np.arange(t) * 0.1, step=np.arange(t) * 100,
        species=np.array([0, 1, 1, 2][:n]), radius=np.full(n, 0.5), mass=np.full(n, 2.0),
        kinematic=np.array([True, False, False, False][:n]),
        box_lower=np.zeros(d), box_upper=np.full(d, 10.0),
        parameters={"young": 1e9, "engine": "lammps", "profile": [[0, 1], [2, 3]], "dt": None},
        observables={"kinetic_energy": np.linspace(0, 1, t)},
    )


def test_round_trip_keeps_every_field(tmp_path):
    traj = make_traj()
    path = h5md.write(tmp_path / "sim.h5", traj)
    back = h5md.read(path)
    np.testing.assert_array_equal(back.position, traj.position)
    np.testing.assert_array_equal(back.time, traj.time)
    np.testing.assert_array_equal(back.kinematic, traj.kinematic)
    np.testing.assert_array_equal(back.species, traj.species)
    assert back.parameters == traj.parameters
    np.testing.assert_allclose(back.observables["kinetic_energy"], traj.observables["kinetic_energy"])
    assert list(tmp_path.iterdir()) == [path]      # no temporary left behind


def test_file_follows_h5md_layout(tmp_path):
    path = h5md.write(tmp_path / "sim.h5", make_traj(d=3))
    with h5py.File(path) as f:
        assert list(f["h5md"].attrs["version"]) == [1, 1]
        assert f["h5md/creator"].attrs["name"] == "graphdem"
        assert f["particles/all/box"].attrs["dimension"] == 3
        assert f["particles/all/position/value"].shape == (5, 4, 3)
        assert f["particles/all/position/value"].dtype == np.float32
        assert f["particles/all/position/value"].chunks == (1, 4, 3)
        assert f["particles/all/kinematic"].dtype == bool


@pytest.mark.parametrize("mutate, message", [
    (lambda t: t.position.__setitem__((2, 1, 0), np.nan), "non-finite position at frame 2, particle 1"),
    (lambda t: setattr(t, "time", np.array([0, 0.1, 0.1, 0.3, 0.4])), "not strictly increasing"),
    (lambda t: setattr(t, "kinematic", None), "kinematic is missing"),
    (lambda t: setattr(t, "radius", np.ones(3)), "radius has shape"),
    (lambda t: setattr(t, "position", np.zeros((5, 4, 4))), "D in \\(2, 3\\)"),
])
def test_invalid_trajectory_is_not_written(tmp_path, mutate, message):
    traj = make_traj()
    mutate(traj)
    with pytest.raises(h5md.H5MDError, match=message):
        h5md.write(tmp_path / "bad.h5", traj)
    assert list(tmp_path.iterdir()) == []


def test_truncated_file_gives_clear_error(tmp_path):
    path = h5md.write(tmp_path / "sim.h5", make_traj())
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(h5md.H5MDError, match=f"{path}.*(corrupt|truncated)"):
        h5md.read(path)


def test_garbage_and_missing_files(tmp_path):
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"not hdf5 at all")
    with pytest.raises(h5md.H5MDError, match="junk.h5: not a readable HDF5 file"):
        h5md.read(junk)
    with pytest.raises(h5md.H5MDError, match="no such file"):
        h5md.read(tmp_path / "absent.h5")


def test_file_missing_a_dataset_names_it(tmp_path):
    path = h5md.write(tmp_path / "sim.h5", make_traj())
    with h5py.File(path, "a") as f:
        del f["particles/all/kinematic"]
    with pytest.raises(h5md.H5MDError, match="missing particles/all/kinematic"):
        h5md.read(path)


def test_corrupted_values_are_caught_on_read(tmp_path):
    path = h5md.write(tmp_path / "sim.h5", make_traj())
    with h5py.File(path, "a") as f:
        f["particles/all/position/value"][3, 2, 1] = np.inf
    with pytest.raises(h5md.H5MDError, match="non-finite position at frame 3, particle 2"):
        h5md.read(path)
