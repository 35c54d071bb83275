"""Stale Snakemake locks are removed only when no other Snakemake process works in the folder."""

import os
import subprocess
import sys
import time

from graphdem_workflow import locks


def make_locks(workdir):
    (workdir / ".snakemake" / "locks").mkdir(parents=True)
    for name in ("0.input.lock", "0.output.lock"):
        (workdir / ".snakemake" / "locks" / name).write_text("results/x.csv\n")


def locks_kept_while_running(proc: subprocess.Popen, workdir) -> None:
    """Once ``proc`` is seen as a Snakemake working in ``workdir`` (within 10 s), its locks are kept."""
    deadline = time.monotonic() + 10
    while proc.pid not in locks.other_snakemake_in(workdir):
        assert time.monotonic() < deadline
        time.sleep(0.05)
    assert locks.remove_stale_locks(workdir) == []
    assert len(list((workdir / ".snakemake" / "locks").iterdir())) == 2


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
        locks_kept_while_running(proc, tmp_path)
        assert locks.other_snakemake_in(tmp_path / "bin") == []      # another folder is not this one
    finally:
        proc.kill()
        proc.wait()


def test_snakemake_is_recognised_however_it_was_started():
    assert locks.is_snakemake(["/venv/bin/snakemake", "-c2", "results/slide/metrics.csv"])
    assert locks.is_snakemake(["/usr/bin/python3", "/venv/bin/snakemake", "-c2"])
    assert locks.is_snakemake(["python", "-m", "snakemake", "-c2"])
    assert locks.is_snakemake(["python3.11", "-X", "dev", "-m", "snakemake", "--unlock"])
    assert not locks.is_snakemake(["python", "-m", "pytest", "snakemake"])
    assert not locks.is_snakemake(["python", "train.py", "snakemake"])
    assert not locks.is_snakemake(["vim", "Snakefile"])


def test_a_snakemake_given_the_folder_by_directory_works_in_it(tmp_path):
    other = tmp_path / "elsewhere"
    assert locks.working_folders(["snakemake", "-d", "runs/a"], tmp_path) == {tmp_path, tmp_path / "runs" / "a"}
    assert other in locks.working_folders(["snakemake", f"--directory={other}"], tmp_path)


def test_locks_of_a_running_python_m_snakemake_are_kept(tmp_path):
    """`python -m snakemake` (argv: python, -m, snakemake) is as live a run as the console script."""
    make_locks(tmp_path)
    module = tmp_path / "mods" / "snakemake"
    module.mkdir(parents=True)
    (module / "__init__.py").write_text("")
    (module / "__main__.py").write_text("import time\ntime.sleep(30)\n")
    env = {**os.environ, "PYTHONPATH": str(tmp_path / "mods")}
    proc = subprocess.Popen([sys.executable, "-m", "snakemake"], cwd=tmp_path, env=env)
    try:
        locks_kept_while_running(proc, tmp_path)
    finally:
        proc.kill()
        proc.wait()
