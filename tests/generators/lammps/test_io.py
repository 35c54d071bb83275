"""LAMMPS' output read back: dump snapshots in id order whatever order they were written in, a log's thermo
tables of its last runs, its loop times, version and error, and the malformed files refused by name."""

import numpy as np
import pytest

from generators.lammps import io

from .raw import snapshot, thermo


def test_dump_snapshots_come_back_in_step_order_sorted_by_id(tmp_path):
    path = tmp_path / "frames.dump"
    path.write_text(snapshot(100, "id x y", [(3, 0.5, 0.25), (1, -0.125, 1.0)])
                    + snapshot(200, "id x y", [(1, -0.25, 0.75), (3, 0.625, 0.0)]))
    frames = io.read_dump(path)
    assert [step for step, _ in frames] == [100, 200]
    for _, table in frames:
        assert list(table["id"]) == [1, 3] and list(table.columns) == ["id", "x", "y"]
    np.testing.assert_array_equal(frames[0][1][["x", "y"]].to_numpy(), [[-0.125, 1.0], [0.5, 0.25]])
    np.testing.assert_array_equal(frames[1][1][["x", "y"]].to_numpy(), [[-0.25, 0.75], [0.625, 0.0]])


@pytest.mark.parametrize("text, message", [
    (None, "dump file missing"),
    ("", "no snapshots"),
    (snapshot(5, "id x", [(1, 0.0), (2, 1.0)]).replace("NUMBER OF ATOMS\n2", "NUMBER OF ATOMS\n3"),
     "snapshot at step 5 has 2 atoms, header says 3"),
    (snapshot(5, "id x", [(1, 0.0)]).replace("TIMESTEP\n5", "TIMESTEP\nfive"), "malformed snapshot"),
])
def test_a_missing_or_malformed_dump_is_refused_naming_the_file(tmp_path, text, message):
    path = tmp_path / "frames.dump"
    if text is not None:
        path.write_text(text)
    with pytest.raises(io.LammpsOutputError, match=message) as info:
        io.read_dump(path)
    assert str(path) in str(info.value)


LOG = "\n".join([
    "LAMMPS (29 Sep 2021 - Update 2)", "run 100",
    thermo("Step Time c_ke", [(0, 0.0, 1.0), (100, 0.01, 2.0)], 100),
    "run 200",
    thermo("Step Time c_ke", [(100, 0.01, 2.5), (200, 0.02, 3.0)], 200, 1.25).replace(
        "Loop time", "WARNING: a lost bond\n300 0.03 9.0\nLoop time"),
    "ERROR: Lost atoms: original 3 current 2 (src/thermo.cpp:439)", ""])


def test_thermo_tables_of_the_last_runs_end_where_their_rows_do(tmp_path):
    log = tmp_path / "log.lammps"
    log.write_text(LOG)
    last = io.read_thermo(log)
    assert list(last.columns) == ["Step", "Time", "c_ke"]
    # the row after the warning is not part of the table: a table ends at its first line that is not a row
    np.testing.assert_array_equal(last.to_numpy(), [[100, 0.01, 2.5], [200, 0.02, 3.0]])
    both = io.read_thermo(log, runs=2)
    np.testing.assert_array_equal(both["Step"], [0, 100, 100, 200])
    assert io.last_step(log) == 200
    assert io.loop_times(log) == [(0.5, 100), (1.25, 200)]
    empty = tmp_path / "empty.lammps"
    empty.write_text("LAMMPS (x)\n")
    assert io.read_thermo(empty).empty and io.last_step(empty) == 0 and io.last_step(tmp_path / "none") == 0


def test_version_and_error_come_from_the_log_and_the_screen(tmp_path):
    log = tmp_path / "log.lammps"
    log.write_text(LOG)
    assert io.version(log) == "29 Sep 2021 - Update 2"
    assert io.error_message(log) == "ERROR: Lost atoms: original 3 current 2 (src/thermo.cpp:439)"
    assert io.error_message(log, "ERROR on proc 0: the last one\n") == "ERROR on proc 0: the last one"
    assert io.error_message(tmp_path / "none", "no error here") == ""
    other = tmp_path / "other.lammps"
    other.write_text("something else\n")
    assert io.version(other) == "unknown"
