"""Stale Snakemake locks are removed only when no other Snakemake process works in the folder."""

import subprocess
import time

from graphdem_workflow import locks


def make_locks(workdir):
    (workdir / ".snakemake" / "locks").mkdir(parents=True)
    for name in ("0.input.lock", "0.output.lock"):
        (workdir / ".snakemake" / "locks" / name).write_text("results/x.csv\n")


def test_locks_of_a_killed_run_are_removed(tmp_path):
    make_locks(tmp_path)
    removed = locks.remove_stale_locks(tmp_path)
    assert sorted(p.name for p in removed) == ["0.input.lock", "0.output.lock"]
    assert list((tmp_path / ".snakemake" / "locks").iterdir()) == []
    assert locks.remove_stale_locks(tmp_path) == []


def test_locks_of_a_running_snakemake_in_the_folder_are_kept(tmp_path):
    make_locks(tmp_path)
    fake = tmp_path / "bin" / "snakemake"
    fake.parent.mkdir()
    fake.write_text("#!/bin/sh\nsleep 30\n")
    fake.chmod(0o755)
    proc = subprocess.Popen([str(fake)], cwd=tmp_path)
    try:
        deadline = time.monotonic() + 10
        while proc.pid not in locks.other_snakemake_in(tmp_path):
            assert time.monotonic() < deadline
            time.sleep(0.05)
        assert locks.remove_stale_locks(tmp_path) == []
        assert len(list((tmp_path / ".snakemake" / "locks").iterdir())) == 2
        assert locks.other_snakemake_in(tmp_path / "bin") == []      # another folder is not this one
    finally:
        proc.kill()
        proc.wait()
