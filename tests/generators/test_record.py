"""Run records: what prepare and simulate write beside their output reads back field for field, and a record that
is missing, not JSON, of an unknown kind or short of a field is refused naming the file and the field."""

import dataclasses
import json
import math

import pytest

from generators import record


def _run(**extra) -> record.EngineRun:
    fields = dict(engine="lammps", version="29 Sep 2021 - Update 2", command="lmp -in in.lammps", wall_time=1.5,
                  max_rss_mb=42.0, window_seconds=0.75, runup_seconds=0.25, steps=1200, ranks=2,
                  notes={"closed": [1, 2]})
    fields.update(extra)
    return record.EngineRun(**fields)


def _sim(**extra) -> record.SimRecord:
    fields = dict(scene="slide", params={"id": "slide_0000", "friction": 0.4}, run=_run(), dt=1e-4, dt_limit=2e-4,
                  steps_per_frame=100, record_start_step=200, n_steps=200 + 100 * 9, window_steps=900,
                  frame_interval=0.01, packing="packings/p0", box_lower=[0.0, 0.0], box_upper=[1.0, 2.0],
                  contact_model="linear", parameters={"young": 1e7}, properties={"friction": [0.4, 0.4]},
                  log_scaled_properties=["young"], kinetic_energy=[0.0, 1.25], observables={"ke": [0.0, 1.25]})
    fields.update(extra)
    return record.SimRecord(**fields)


def test_a_sim_record_reads_back_equal_from_the_file_and_from_its_folder(tmp_path):
    rec = _sim()
    record.write(tmp_path / record.RUN_FILE, rec)
    assert record.read(tmp_path / record.RUN_FILE) == rec
    assert record.read(tmp_path) == rec                                    # a folder: its run.json
    assert record.read(tmp_path).window_seconds == rec.run.window_seconds == 0.75


def test_a_packing_record_reads_back_with_its_kind_and_default_fields(tmp_path):
    rec = record.PackingRecord(scene="collapse", params={"aspect": 2.0}, run=record.EngineRun("yade", "2023", "yade",
                                                                                               3.0),
                               dt=1e-5, dt_limit=3e-5, settle_steps=4000, n_moving=90, n_kinematic=10)
    record.write(tmp_path / "run.json", rec)
    back = record.read(tmp_path)
    assert isinstance(back, record.PackingRecord) and back.kind == "packing"
    assert math.isnan(back.run.max_rss_mb)                # the default survives JSON as NaN
    assert dataclasses.replace(back, run=dataclasses.replace(back.run, max_rss_mb=0.0)) == \
        dataclasses.replace(rec, run=dataclasses.replace(rec.run, max_rss_mb=0.0))


def test_fields_a_reader_does_not_know_are_ignored(tmp_path):
    data = dataclasses.asdict(_sim())
    data["from_a_later_version"] = 1
    data["run"]["also_later"] = "x"
    (tmp_path / "run.json").write_text(json.dumps(data))
    assert record.read(tmp_path) == _sim()


def _write(path, data) -> None:
    path.write_text(data if isinstance(data, str) else json.dumps(data))


@pytest.mark.parametrize("content, message", [
    (None, "no run record"),
    ("{not json", "run record is not valid JSON"),
    ([1, 2], "run record has kind None; allowed: \\['packing', 'sim'\\]"),
    ({"kind": "mesh"}, "run record has kind 'mesh'"),
])
def test_a_missing_or_malformed_record_is_refused_naming_the_file(tmp_path, content, message):
    path = tmp_path / "run.json"
    if content is not None:
        _write(path, content)
    with pytest.raises(record.RecordError, match=message) as info:
        record.read(tmp_path)
    assert str(path) in str(info.value)


def test_a_record_short_of_a_field_is_refused_naming_the_fields(tmp_path):
    data = dataclasses.asdict(_sim())
    del data["dt"], data["window_steps"]
    _write(tmp_path / "run.json", data)
    with pytest.raises(record.RecordError, match=r"run.json: run record lacks the field\(s\) \['dt', 'window_steps'\]"):
        record.read(tmp_path)
    data = dataclasses.asdict(_sim())
    del data["run"]["wall_time"]
    _write(tmp_path / "run.json", data)
    with pytest.raises(record.RecordError, match=r"run.json \(run\): run record lacks the field\(s\) \['wall_time'\]"):
        record.read(tmp_path)
    data = dataclasses.asdict(_sim())
    del data["kinetic_energy"], data["observables"]                        # optional fields take their defaults
    _write(tmp_path / "run.json", data)
    back = record.read(tmp_path)
    assert back.kinetic_energy is None and back.observables == {}
