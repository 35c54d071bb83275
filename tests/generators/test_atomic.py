"""Atomic writes: a killed writer's temporary is removed by the next write of the same path."""

import os
import subprocess

from generators.atomic import atomic_path, remove_stale


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
