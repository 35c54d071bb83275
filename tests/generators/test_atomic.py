"""Atomic writes: a killed writer's temporary is removed by the next write of the same path; a folder is never
replaced by a file (nor a file by a folder, nor a foreign folder by a folder output); a failed write names the output
and leaves what was there; the outputs of one group appear together or not at all."""

import errno
import os
import subprocess

import h5py
import numpy as np
import pytest

from generators.atomic import OutputError, atomic_outputs, atomic_path, h5_file, remove_stale


def dead_pid() -> int:
    proc = subprocess.Popen(["true"])
    proc.wait()
    return proc.pid


def test_the_temporary_of_a_killed_writer_is_removed_and_a_live_ones_kept(tmp_path):
    dead = tmp_path / f".sim.tmp-{dead_pid()}.h5"
    dead.write_bytes(b"half")
    folder = tmp_path / f".sim.tmp-{dead_pid()}.h5"
    folder.mkdir()
    (folder / "x").write_text("half")
    live = tmp_path / f".sim.tmp-{os.getppid()}.h5"
    live.write_bytes(b"someone else's")
    with atomic_path(tmp_path / "sim.h5") as tmp:
        tmp.write_bytes(b"done")
    assert (tmp_path / "sim.h5").read_bytes() == b"done"
    assert not dead.exists() and not folder.exists() and live.exists()
    assert remove_stale(tmp_path / "sim.h5") == []


def test_an_existing_folder_is_never_replaced_by_a_file(tmp_path):
    model = tmp_path / "model"
    model.mkdir()
    (model / "best.pt").write_bytes(b"weights")
    with pytest.raises(OutputError, match=f"^{model}: is an existing folder, which a file output does not replace"):
        with atomic_path(model) as tmp:
            tmp.write_text("metrics")
    assert (model / "best.pt").read_bytes() == b"weights" and os.listdir(tmp_path) == ["model"]
    table = tmp_path / "table.csv"
    table.write_text("old")
    with pytest.raises(OutputError, match="is an existing file, which a folder output does not replace"):
        with atomic_path(table) as tmp:
            tmp.mkdir()
    assert table.read_text() == "old" and sorted(os.listdir(tmp_path)) == ["model", "table.csv"]


def test_a_folder_output_replaces_an_earlier_one_of_its_kind_but_not_a_foreign_folder(tmp_path):
    series = tmp_path / "dem"
    for frames in ((0, 5, 10), (0, 20)):               # other frames: the same kind of output
        with atomic_path(series) as tmp:
            tmp.mkdir()
            for frame in frames:
                (tmp / f"frame_{frame:06d}.vtu").write_text(str(frame))
    assert sorted(os.listdir(series)) == ["frame_000000.vtu", "frame_000020.vtu"]
    for name in ("best.pt", "history.csv"):
        (series / name).write_text("training")
    with pytest.raises(OutputError, match=r"dem: is an existing folder that does not hold an earlier output of "
                                          r"this kind \(best.pt, frame_000000.vtu"):
        with atomic_path(series) as tmp:
            tmp.mkdir()
            (tmp / "frame_000000.vtu").write_text("new")
    assert sorted(os.listdir(series)) == ["best.pt", "frame_000000.vtu", "frame_000020.vtu", "history.csv"]
    assert (series / "frame_000000.vtu").read_text() == "0" and os.listdir(tmp_path) == ["dem"]


def test_a_failed_write_names_the_output_and_leaves_the_previous_one(tmp_path):
    out = tmp_path / "metrics.csv"
    out.write_text("previous")
    for error in (OSError(errno.EFBIG, "File too large"), OSError(errno.ENOSPC, "No space left on device")):
        with pytest.raises(OutputError, match=f"^{out}: cannot be written: {error.strerror}$"):
            with atomic_path(out) as tmp:
                tmp.write_text("half")
                raise error
        assert out.read_text() == "previous" and os.listdir(tmp_path) == ["metrics.csv"]
    # an error of reading something else in the block is not called a failed write of the output
    with pytest.raises(FileNotFoundError, match="missing.csv"), atomic_path(out) as tmp:
        (tmp_path / "missing.csv").read_text()
    # nested (a writer that writes its own output atomically, given the temporary): the output is named
    with pytest.raises(OutputError, match=f"^{out}: cannot be written: File too large$"):
        with atomic_path(out) as tmp, atomic_path(tmp):
            raise OSError(errno.EFBIG, "File too large")
    assert out.read_text() == "previous" and os.listdir(tmp_path) == ["metrics.csv"]


def test_outputs_of_one_group_appear_together_or_not_at_all(tmp_path):
    first, second = tmp_path / "metrics.csv", tmp_path / "plots" / "curve.png"
    first.write_text("previous")
    with pytest.raises(ValueError, match="the plot failed"), atomic_outputs() as output:
        with output(first) as tmp:
            tmp.write_text("new")
        with output(second) as tmp:
            raise ValueError("the plot failed")
    # the first, written, is not renamed into place; the plots folder made for the second is gone again
    assert first.read_text() == "previous" and os.listdir(tmp_path) == ["metrics.csv"]
    with atomic_outputs() as output:
        for path, text in ((first, "new"), (second, "png")):
            with output(path) as tmp:
                tmp.write_text(text)
        assert first.read_text() == "previous"           # nothing moves before the group ends
    assert first.read_text() == "new" and second.read_text() == "png"
    assert sorted(os.listdir(tmp_path)) == ["metrics.csv", "plots"] and os.listdir(second.parent) == ["curve.png"]
    with pytest.raises(OutputError, match="metrics.csv: is given for two outputs of one command"):
        with atomic_outputs() as output, output(first) as tmp, output(first):
            tmp.write_text("twice")
    assert first.read_text() == "new"


def test_a_folder_moved_aside_by_a_killed_writer_is_put_back(tmp_path):
    old = tmp_path / f".raw.old-{dead_pid()}"
    old.mkdir()
    (old / "run.json").write_text("{}")
    assert remove_stale(tmp_path / "raw") == [old]
    assert (tmp_path / "raw" / "run.json").read_text() == "{}" and not old.exists()


def test_an_h5_file_is_built_in_memory_and_written_in_one_go(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with atomic_path(tmp_path / "a.h5") as tmp, h5_file(tmp) as f:
        f.create_dataset("x", data=np.arange(5))
        assert os.listdir(tmp_path) == []                # nothing on the disk while it is built
    with h5py.File(tmp_path / "a.h5", "r") as f:
        np.testing.assert_array_equal(f["x"][()], np.arange(5))
    assert os.listdir(tmp_path) == ["a.h5"]
