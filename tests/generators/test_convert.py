"""Convert a raw run folder into H5MD: a hand-written LAMMPS folder of a collapse sim (a fixed floor disc and two
grains over three frames) comes out with the dumped positions, the fixed disc where the data file puts it, the
record's parameters, properties and observables (each with the unit its scene declares), and a folder the file
cannot be made from is refused by name.
A write that fails (a file-size limit) or may not replace what is at the path (a folder) leaves that as it was,
with one line naming the file."""

import os
import resource
import subprocess
import sys

import h5py
import numpy as np
import pytest

from generators import convert, h5md, record
from generators.atomic import OutputError
from generators.scenes import collapse

from .lammps.raw import write_run

X = np.array([[0.002, 0.002], [0.01, 0.0065], [0.014, 0.0085]])
RADIUS = np.array([0.002, 0.0018, 0.0022])
SPECIES = np.array([collapse.FLOOR, collapse.GRAIN, collapse.GRAIN])
MASS = np.array([0.0, 0.027, 0.040])
STEPS = [0, 50, 100]
DT = 2e-5
# the grains slide along +x by 1 mm a frame
MOVING = np.stack([X[1:] + [1e-3 * k, 0.0] for k in range(3)])


def _record(**extra) -> record.SimRecord:
    run = record.EngineRun("lammps", "29 Sep 2021 - Update 2", "lmp -in in.lammps", 2.0, ranks=1)
    fields = dict(scene="collapse", params={"id": "collapse_0001", "friction": 0.5, "aspect": 1.0}, run=run, dt=DT,
                  dt_limit=1e-4, steps_per_frame=50, record_start_step=0, n_steps=100, window_steps=100,
                  frame_interval=50 * DT, packing="p0", box_lower=[0.0, 0.0], box_upper=[0.1, 0.05],
                  contact_model="linear", parameters={"floor_top": 0.004}, properties={"friction": 0.5},
                  log_scaled_properties=[], kinetic_energy=[0.0, 1e-6, 2e-6], observables={})
    fields.update(extra)
    return record.SimRecord(**fields)


def _raw(tmp_path, rec=None, moving=MOVING):
    raw = tmp_path / "raw"
    write_run(raw, X, RADIUS, SPECIES, MASS, STEPS, moving)
    record.write(raw / record.RUN_FILE, rec or _record())
    return raw


def test_a_raw_folder_becomes_the_trajectory_it_recorded(tmp_path):
    traj = h5md.read(convert.convert(_raw(tmp_path), tmp_path / "sim.h5"))
    np.testing.assert_allclose(traj.position[:, 1:], MOVING, rtol=1e-6)     # float32 of the dumped values
    np.testing.assert_allclose(traj.position[:, 0], np.repeat(X[:1], 3, axis=0), rtol=1e-6)
    np.testing.assert_array_equal(traj.kinematic, [True, False, False])       # the collapse floor is kinematic
    np.testing.assert_array_equal(traj.step, STEPS)
    np.testing.assert_allclose(traj.time, np.array(STEPS) * DT)
    np.testing.assert_allclose(traj.radius, RADIUS)
    np.testing.assert_allclose(traj.mass, MASS)
    np.testing.assert_array_equal(traj.box_upper, [0.1, 0.05])
    assert traj.boundary == ("none", "none")
    assert traj.property_names == ("friction",)
    np.testing.assert_allclose(traj.properties, np.full((3, 1), 0.5))


def test_parameters_and_observables_come_from_the_run_record(tmp_path, monkeypatch):
    monkeypatch.setattr(collapse.SCENE, "observable_units", {"front": "m"})     # a scene observable, in metres
    traj = convert.trajectory(_raw(tmp_path, _record(observables={"front": [1.0, 2.0, 3.0]})))
    p = traj.parameters
    assert p["id"] == "collapse_0001" and p["friction"] == 0.5 and p["floor_top"] == 0.004
    assert p["scene"] == "collapse" and p["engine"] == "lammps" and p["engine_version"] == "29 Sep 2021 - Update 2"
    assert p["dem_time_step"] == DT and p["steps_per_frame"] == 50 and p["frame_interval"] == 50 * DT
    assert p["species_names"] == {"0": "floor", "1": "grain"} and "log_scaled_properties" not in p
    np.testing.assert_array_equal(traj.observables["kinetic_energy"], [0.0, 1e-6, 2e-6])
    np.testing.assert_array_equal(traj.observables["front"], [1.0, 2.0, 3.0])
    assert traj.observable_units == {"kinetic_energy": "J", "front": "m"}
    with h5py.File(h5md.write(tmp_path / "sim.h5", traj)) as f:              # the units module's unit attribute
        assert {k: f[f"observables/{k}/value"].attrs["unit"] for k in f["observables"]} == \
            {"kinetic_energy": "J", "front": "m"}
    # a kinetic energy of another length than the frames is left out, not stored misaligned
    short = convert.trajectory(_raw(tmp_path / "short", _record(kinetic_energy=[0.0, 1.0])))
    assert "kinetic_energy" not in short.observables


def test_a_folder_the_file_cannot_be_made_from_is_refused_by_name(tmp_path):
    with pytest.raises(h5md.H5MDError, match=r"observable 'front' has 2 values for 3 frames"):
        convert.trajectory(_raw(tmp_path / "a", _record(observables={"front": [1.0, 2.0]})))
    with pytest.raises(h5md.H5MDError, match=r"observable 'front' has no unit: the collapse scene declares units "
                                             r"for no observables"):
        convert.trajectory(_raw(tmp_path / "u", _record(observables={"front": [1.0, 2.0, 3.0]})))
    packing = record.PackingRecord("collapse", {}, _record().run, DT, 1e-4, 10, 2, 1)
    raw = _raw(tmp_path / "b")
    record.write(raw / record.RUN_FILE, packing)
    with pytest.raises(record.RecordError, match="a packing record, not a simulation's"):
        convert.trajectory(raw)
    # a grain missing from the frames dump: the fixed floor is taken from the data file, a grain never is
    lost = tmp_path / "c" / "raw"
    write_run(lost, X, RADIUS, SPECIES, MASS, STEPS, MOVING[:, :1], dumped=np.array([False, True, False]))
    record.write(lost / record.RUN_FILE, _record())
    with pytest.raises(h5md.H5MDError, match="did not record every moving particle \\(1 missing\\)"):
        convert.trajectory(lost)


def _convert_limited(raw, out, limit: int) -> subprocess.CompletedProcess:
    """`graphdem convert` in a process that may write files of at most ``limit`` bytes (``ulimit -f``)."""
    def cap():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return subprocess.run([sys.executable, "-m", "graphdem", "convert", "--raw", str(raw), "--out", str(out)],
                          capture_output=True, text=True, preexec_fn=cap, timeout=120)


def test_a_file_size_limit_leaves_the_previous_file_and_says_so_in_one_line(tmp_path):
    raw = _raw(tmp_path)
    out = convert.convert(raw, tmp_path / "sims" / "sim.h5")
    before = out.read_bytes()
    assert len(before) > 16384
    done = _convert_limited(raw, out, 8192)                # HDF5 used to crash here (SIGSEGV, 139)
    assert (done.returncode, done.stderr) == (1, f"graphdem convert: error: {out}: cannot be written: File too large\n")
    assert out.read_bytes() == before and os.listdir(out.parent) == ["sim.h5"]     # no temporary, no new file
    fresh = tmp_path / "new" / "sim.h5"                  # nothing half-written where there was nothing
    assert _convert_limited(raw, fresh, 8192).returncode == 1 and not fresh.parent.exists()
    done = _convert_limited(raw, fresh, 2 ** 20)         # room enough: the same file as written in-process
    assert done.returncode == 0 and fresh.read_bytes() == before


def test_an_existing_folder_at_the_output_path_is_refused_not_replaced(tmp_path):
    model = tmp_path / "model"
    model.mkdir()
    (model / "best.pt").write_bytes(b"weights")
    with pytest.raises(OutputError, match=f"{model}: is an existing folder, which a file output does not replace"):
        convert.convert(_raw(tmp_path), model)
    assert os.listdir(model) == ["best.pt"] and (model / "best.pt").read_bytes() == b"weights"
