"""The import folder: replaced whole by a later import of the same name and layout, left as it was by a refused
import, and a folder that is no import (or another name's) never replaced."""

import json

import numpy as np
import pytest

from graphdem import cli


def npz(path, frames: int, trajectories: int = 1) -> None:
    entries = {}
    for i in range(trajectories):
        entry = np.empty(2, dtype=object)
        entry[:] = [np.arange(frames * 4, dtype=np.float64).reshape(frames, 2, 2) + i, np.array([0, 1])]
        entries[f"simulation_trajectory_{i}"] = entry
    np.savez(path, **entries)


def run(src, out, *more) -> int:
    return cli.main(["import", "gns", str(src), str(out), "--radius", "0.5", "--mass", "1", "--dt", "0.1",
                     "--box", "0", "100", "0", "100", *more])


def test_an_import_replaces_an_earlier_one_whole_and_a_refused_one_leaves_it(tmp_path, capsys):
    npz(tmp_path / "a.npz", 3, trajectories=2)
    out = tmp_path / "out"
    assert run(tmp_path / "a.npz", out) == 0
    assert sorted(p.name for p in out.iterdir()) == ["a_0000.h5", "a_0001.h5", "import.json"]
    assert run(tmp_path / "a.npz", out, "--limit", "1") == 0
    assert sorted(p.name for p in out.iterdir()) == ["a_0000.h5", "import.json"]
    assert json.loads((out / "import.json").read_text())["limit"] == 1
    npz(tmp_path / "one.npz", 1)                                     # one frame: not a trajectory
    assert run(tmp_path / "one.npz", out, "--name", "a") == 1
    assert "one.npz: simulation_trajectory_0: positions must be numbers of shape [T, N, D] with at least 2 frames" \
        in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["a_0000.h5", "import.json"]
    assert run(tmp_path / "a.npz", out, "--name", "b") == 1                 # another name's files: not replaced
    assert "is an existing folder that does not hold an earlier output of this kind" in capsys.readouterr().err
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(SystemExit, match="mine is an existing folder that is not a previous output of this command"):
        run(tmp_path / "a.npz", tmp_path / "mine")
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep"
    assert run(tmp_path / "a.npz", tmp_path / "x", "--name", "slide") == 1
    assert "--name 'slide' is a registered scene's" in capsys.readouterr().err
