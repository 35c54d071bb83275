"""ParaView export: every exported number is read back from the .vtu and .pvd files and compared with the source."""

from dataclasses import replace

import meshio
import numpy as np
import pytest

from generators import export, h5md
from graphdem import cli

TIMES = np.array([0.0, 0.1, 0.25, 0.3, 0.5, 0.55, 0.8])          # uneven on purpose: velocity divides by each gap


def make_traj(d: int, t: int = len(TIMES), n: int = 5, seed: int = 0) -> h5md.Trajectory:
    """A small H5MD trajectory with two properties and one kinematic particle."""
    rng = np.random.default_rng(seed)
    return h5md.Trajectory(
        position=rng.uniform(0, 10, (t, n, d)).astype(np.float32),
        time=TIMES[:t].copy(), step=np.arange(t) * 100,
        species=np.array([0, 1, 1, 2, 2][:n], np.int32), radius=np.linspace(0.2, 0.6, n).astype(np.float32),
        mass=np.linspace(1.0, 3.0, n).astype(np.float32), kinematic=np.array([True, False, False, False, False][:n]),
        box_lower=np.zeros(d), box_upper=np.full(d, 10.0),
        properties=np.stack([np.linspace(1e9, 5e9, n), np.arange(n) + 0.5], axis=1).astype(np.float32),
        property_names=("young", "friction"),
    )


def series(pvd):
    """The (time, mesh) of every frame of a written series, read back with meshio."""
    return [(t, meshio.read(path)) for t, path in export.read_pvd(pvd)]


def expected_velocity(position: np.ndarray, time: np.ndarray) -> np.ndarray:
    """The documented rule, frame by frame: backward difference, the first frame the forward one."""
    x = position.astype(np.float64)
    out = np.empty_like(x)
    for k in range(len(time)):
        a, b = (k - 1, k) if k > 0 else (0, 1)
        out[k] = (x[b] - x[a]) / (time[b] - time[a])
    return out


@pytest.mark.parametrize("d", [2, 3])
def test_every_frame_is_read_back_with_its_time_positions_and_point_data(tmp_path, d):
    traj = make_traj(d)
    path = h5md.write(tmp_path / "sim.h5", traj)
    written = export.export_file(path, tmp_path / "out" / "dem.pvd")
    assert written.frames == tuple(range(len(TIMES)))
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["dem", "dem.pvd"]    # no temporaries
    frames = series(tmp_path / "out" / "dem.pvd")
    assert [t for t, _ in frames] == TIMES.tolist()                                      # exact frame times
    assert [p.name for _, p in export.read_pvd(tmp_path / "out" / "dem.pvd")][:2] == ["frame_000000.vtu",
                                                                                       "frame_000001.vtu"]
    velocity = expected_velocity(traj.position, TIMES)
    for k, (_, mesh) in enumerate(frames):
        np.testing.assert_array_equal(mesh.points[:, :d], traj.position[k])
        if d == 2:
            np.testing.assert_array_equal(mesh.points[:, 2], 0.0)
        np.testing.assert_array_equal(mesh.cells[0].data[:, 0], np.arange(5))
        assert mesh.cells[0].type == "vertex"
        data = mesh.point_data
        assert set(data) == {"id", "type", "radius", "mass", "kinematic", "velocity", "young", "friction"}
        np.testing.assert_array_equal(data["id"], np.arange(5))
        np.testing.assert_array_equal(data["type"], [0, 1, 1, 2, 2])
        np.testing.assert_array_equal(data["radius"], traj.radius)
        np.testing.assert_array_equal(data["mass"], traj.mass)
        np.testing.assert_array_equal(data["kinematic"], [1, 0, 0, 0, 0])
        np.testing.assert_array_equal(data["young"], traj.properties[:, 0])
        np.testing.assert_array_equal(data["friction"], [0.5, 1.5, 2.5, 3.5, 4.5])
        assert data["velocity"].shape == (5, 3)
        np.testing.assert_allclose(data["velocity"][:, :d], velocity[k], rtol=1e-12)
        if d == 2:
            np.testing.assert_array_equal(data["velocity"][:, 2], 0.0)


def test_velocity_of_uniform_motion_is_exact_and_the_first_frame_takes_the_forward_difference():
    t = np.array([0.0, 0.5, 2.0, 2.1])
    x = np.array([[[1.0, 2.0]], [[2.0, 2.0]], [[5.0, 1.0]], [[5.1, 1.0]]])   # one particle
    v = export.velocity(x, t)
    np.testing.assert_allclose(v[:, 0], [[2.0, 0.0], [2.0, 0.0], [2.0, -2 / 3], [1.0, 0.0]], rtol=1e-12)
    with pytest.raises(export.ExportError, match="at least 2 frames"):
        export.velocity(x[:1], t[:1])


@pytest.mark.parametrize("d", [2, 3])
def test_a_rollout_carries_its_error_against_the_truth(tmp_path, d):
    truth = make_traj(d)
    rng = np.random.default_rng(1)
    direction = rng.normal(size=(len(TIMES), 5, d))
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    distance = rng.uniform(0.0, 0.3, (len(TIMES), 5))
    distance[:2] = 0.0                                                  # the history frames are the data's
    rollout = replace(truth, position=(truth.position + direction * distance[..., None]).astype(np.float32))
    h5md.write(tmp_path / "dem.h5", truth)
    h5md.write(tmp_path / "rollout.h5", rollout)
    export.export_file(tmp_path / "rollout.h5", tmp_path / "graphdem.pvd", truth=tmp_path / "dem.h5")
    for k, (t, mesh) in enumerate(series(tmp_path / "graphdem.pvd")):
        assert t == TIMES[k]
        np.testing.assert_array_equal(mesh.points[:, :d], rollout.position[k])
        expected = np.linalg.norm(rollout.position[k].astype(float) - truth.position[k].astype(float), axis=-1)
        np.testing.assert_allclose(mesh.point_data["error"], expected, rtol=1e-12, atol=0)
        np.testing.assert_allclose(mesh.point_data["error"], distance[k], rtol=1e-5, atol=1e-5)   # float32 positions
        np.testing.assert_allclose(mesh.point_data["error_radii"], expected / truth.radius.astype(float), rtol=1e-12)
        np.testing.assert_allclose(mesh.point_data["velocity"][:, :d],
                                   expected_velocity(rollout.position, TIMES)[k], rtol=1e-12)
    assert set(series(tmp_path / "graphdem.pvd")[0][1].point_data) >= {"error", "error_radii"}


def test_every_k_exports_every_kth_frame_with_velocities_of_the_recorded_frames(tmp_path):
    traj = make_traj(2)
    written = export.export(traj, tmp_path / "s.pvd", every=3)
    assert written.frames == (0, 3, 6)
    frames = series(tmp_path / "s.pvd")
    assert [t for t, _ in frames] == [TIMES[0], TIMES[3], TIMES[6]]
    assert sorted(p.name for p in (tmp_path / "s").iterdir()) == ["frame_000000.vtu", "frame_000003.vtu",
                                                                   "frame_000006.vtu"]
    velocity = expected_velocity(traj.position, TIMES)
    for (_, mesh), k in zip(frames, (0, 3, 6), strict=True):
        np.testing.assert_array_equal(mesh.points[:, :2], traj.position[k])
        np.testing.assert_allclose(mesh.point_data["velocity"][:, :2], velocity[k], rtol=1e-12)


def test_a_blown_up_rollout_is_exported_with_nan_where_it_is_not_finite(tmp_path):
    truth = make_traj(2)
    position = truth.position.copy()
    position[5:, 2] = np.nan
    h5md.write(tmp_path / "dem.h5", truth)
    h5md.write(tmp_path / "rollout.h5", replace(truth, position=position), allow_nonfinite=True)
    export.export_file(tmp_path / "rollout.h5", tmp_path / "r.pvd", truth=tmp_path / "dem.h5")
    frames = series(tmp_path / "r.pvd")
    assert np.isnan(frames[5][1].points[2, :2]).all() and np.isnan(frames[6][1].point_data["error"][2])
    np.testing.assert_array_equal(frames[5][1].point_data["error"][[0, 1, 3, 4]], 0.0)
    assert np.isfinite(frames[4][1].point_data["error"]).all()


def test_a_property_named_like_a_point_field_is_prefixed(tmp_path):
    traj = replace(make_traj(2), property_names=("radius", "error"))
    export.export(traj, tmp_path / "s.pvd", truth=traj)
    data = series(tmp_path / "s.pvd")[0][1].point_data
    np.testing.assert_array_equal(data["property_radius"], traj.properties[:, 0])
    np.testing.assert_array_equal(data["property_error"], traj.properties[:, 1])
    np.testing.assert_array_equal(data["radius"], traj.radius)
    np.testing.assert_array_equal(data["error"], 0.0)


def test_a_new_export_replaces_the_old_series_whole(tmp_path):
    export.export(make_traj(2), tmp_path / "s.pvd")
    export.export(make_traj(2, t=3, seed=5), tmp_path / "s.pvd")
    assert [t for t, _ in export.read_pvd(tmp_path / "s.pvd")] == TIMES[:3].tolist()
    assert len(list((tmp_path / "s").iterdir())) == 3                     # no stale frame of the longer series
    np.testing.assert_array_equal(series(tmp_path / "s.pvd")[2][1].points[:, :2], make_traj(2, t=3, seed=5).position[2])


def test_a_failed_export_leaves_the_previous_series_and_no_temporaries(tmp_path, monkeypatch):
    old = make_traj(2)
    export.export(old, tmp_path / "s.pvd")
    before = {p.name: p.read_bytes() for p in (tmp_path / "s").iterdir()}
    pvd = (tmp_path / "s.pvd").read_bytes()
    calls = []

    def failing_write(self, path, file_format=None):
        calls.append(path)
        if len(calls) == 3:
            raise OSError("disk full")
        return meshio.write(path, self, file_format)

    monkeypatch.setattr(meshio.Mesh, "write", failing_write)
    with pytest.raises(OSError, match="disk full"):
        export.export(make_traj(2, seed=9), tmp_path / "s.pvd")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s", "s.pvd"]
    assert (tmp_path / "s.pvd").read_bytes() == pvd
    assert {p.name: p.read_bytes() for p in (tmp_path / "s").iterdir()} == before
    with pytest.raises(OSError, match="disk full"):
        calls.clear()
        export.export(make_traj(2, seed=9), tmp_path / "new.pvd")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s", "s.pvd"]      # no half-written new series


@pytest.mark.parametrize("change, message", [
    (lambda t: replace(t, position=t.position[:, :4], species=t.species[:4], radius=t.radius[:4], mass=t.mass[:4],
                       kinematic=t.kinematic[:4], properties=t.properties[:4]),
     r"rollout.h5 has 4 particles but the truth .*dem.h5 has 5"),
    (lambda t: replace(t, position=t.position[:5], time=t.time[:5], step=t.step[:5]),
     r"rollout.h5 has 5 frames .* but the truth .*dem.h5 has 7 .*frame times must match"),
    (lambda t: replace(t, time=t.time * 2), r"frame times must match"),
    (lambda t: replace(t, species=t.species[::-1].copy()), r"different species: not the same particles"),
    (lambda t: replace(t, position=np.concatenate([t.position, t.position[..., :1]], axis=-1),
                       box_lower=np.zeros(3), box_upper=np.full(3, 10.0)), r"rollout.h5 is 3D but the truth"),
])
def test_a_truth_of_other_particles_or_frames_is_refused_naming_both(tmp_path, change, message):
    truth = make_traj(2)
    h5md.write(tmp_path / "dem.h5", truth)
    h5md.write(tmp_path / "rollout.h5", change(truth))
    with pytest.raises(export.ExportError, match=message):
        export.export_file(tmp_path / "rollout.h5", tmp_path / "r.pvd", truth=tmp_path / "dem.h5")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dem.h5", "rollout.h5"]


@pytest.mark.parametrize("every", [0, -2, 1.5, True])
def test_a_bad_every_is_refused(tmp_path, every):
    with pytest.raises(export.ExportError, match="every must be a positive whole number"):
        export.export(make_traj(2), tmp_path / "s.pvd", every=every)
    assert list(tmp_path.iterdir()) == []


def test_the_command_line_exports_a_rollout_against_its_truth(tmp_path, capsys):
    truth = make_traj(3)
    h5md.write(tmp_path / "dem.h5", truth)
    h5md.write(tmp_path / "rollout.h5", replace(truth, position=truth.position + np.float32(0.25)))
    out = tmp_path / "vtk" / "sim" / "graphdem.pvd"
    assert cli.main(["export", str(tmp_path / "rollout.h5"), "--truth", str(tmp_path / "dem.h5"), "--out", str(out),
                     "--every", "2"]) == 0
    assert f"{out}: 4 frames (every 2)" in capsys.readouterr().out
    frames = series(out)
    assert [t for t, _ in frames] == TIMES[::2].tolist()
    np.testing.assert_allclose(frames[-1][1].point_data["error"], 0.25 * np.sqrt(3), rtol=1e-5)


@pytest.mark.parametrize("argv, message", [
    (["missing.h5", "--out", "s.pvd"], "graphdem export: error: missing.h5: no such file"),
    (["dem.h5", "--out", "s.vtu"], "graphdem export: error: s.vtu: a series is written as a .pvd file"),
    (["dem.h5", "--out", "s.pvd", "--truth", "gone.h5"], "graphdem export: error: gone.h5: no such file"),
    (["dem.h5", "--out", "dem.h5"], "--out dem.h5 would overwrite the input TRAJECTORY dem.h5"),
    (["sims/dem.h5", "--out", "sims.pvd"],
     "--out sims.pvd (its frames folder sims) would overwrite the input TRAJECTORY sims/dem.h5"),
    (["dem.h5", "--out", "s.pvd", "--every", "0"], "argument --every: expected a whole number >= 1, got '0'"),
    (["dem.h5", "--out", "s.pvd", "--every", "two"], "argument --every: expected a whole number >= 1, got 'two'"),
])
def test_the_command_line_names_what_is_wrong(tmp_path, capsys, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    h5md.write(tmp_path / "dem.h5", make_traj(2))
    (tmp_path / "sims").mkdir()
    h5md.write(tmp_path / "sims" / "dem.h5", make_traj(2))
    try:
        code = cli.main(["export", *argv])
    except SystemExit as exc:
        code = exc.code
    assert code not in (0, None)
    assert message in str(code) + capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dem.h5", "sims"]
    assert [p.name for p in (tmp_path / "sims").iterdir()] == ["dem.h5"]
