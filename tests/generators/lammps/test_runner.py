"""Running `lmp` on a deck: what a run reports (command, version, ranks, cost), a failure as an error with the
last thermo step it reached, and a launcher whose ranks are not LAMMPS' own refused."""

import stat

import pytest

from generators.lammps import runner

pytestmark = pytest.mark.engine

# An empty box of LJ units run 100 steps with thermo output every 50: the smallest deck that runs.
EMPTY = "\n".join(["units lj", "atom_style atomic", "region box block 0 1 0 1 0 1", "create_box 1 box", "mass 1 1.0",
                   "thermo 50", "run 100", ""])


def test_a_run_reports_its_command_version_and_cost(tmp_path):
    run = runner.run(EMPTY, tmp_path)
    assert (tmp_path / "in.lammps").read_text() == EMPTY
    assert run.engine == "lammps" and run.ranks == 1 and run.version.startswith("29 Sep 2021")
    assert run.command.endswith("lmp -in in.lammps -log log.lammps -screen none -nocite")
    assert run.wall_time > 0 and run.max_rss_mb > 1
    assert runner.ranks_of(tmp_path / "log.lammps") == 1


def test_a_failing_deck_raises_its_error_and_the_last_step_reached(tmp_path):
    with pytest.raises(runner.LammpsError, match=r"LAMMPS failed \(ERROR: Unknown command: no_such_command") as info:
        runner.run(EMPTY + "no_such_command 1\n", tmp_path)
    assert info.value.step == 100                       # its last thermo output
    with pytest.raises(runner.LammpsError) as info:
        runner.run("units lj\nno_such_command 1\n", tmp_path)
    assert info.value.step == 0                         # before any thermo output


def test_ranks_of_reads_the_last_run_of_a_log(tmp_path):
    log = tmp_path / "log.lammps"
    log.write_text("Loop time of 0.1 on 4 procs for 10 steps with 3 atoms\n"
                   "Loop time of 0.2 on 2 procs for 10 steps with 3 atoms\n")
    assert runner.ranks_of(log) == 2
    log.write_text("no run\n")
    assert runner.ranks_of(log) is None and runner.ranks_of(tmp_path / "missing") is None


def test_a_launcher_that_runs_a_serial_lmp_is_refused(tmp_path, monkeypatch):
    # a stand-in mpirun that drops its own options and runs lmp once: LAMMPS reports 1 proc, 2 were asked for
    fake = tmp_path / "mpirun"
    fake.write_text('#!/bin/sh\nwhile [ "$#" -gt 0 ] && [ "${1##*/}" != lmp ]; do shift; done\nexec "$@"\n')
    fake.chmod(fake.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv(runner.MPIRUN_ENV, str(fake))
    work = tmp_path / "work"
    work.mkdir()
    assert str(fake) in runner.command(2)
    with pytest.raises(runner.MpiMismatch, match="LAMMPS ran on 1 MPI rank\\(s\\), 2 asked for"):
        runner.run(EMPTY, work, ranks=2)


def test_a_missing_executable_is_named_with_the_variable_that_sets_it(monkeypatch):
    monkeypatch.setenv(runner.EXECUTABLE_ENV, "no-such-lmp")
    with pytest.raises(FileNotFoundError, match=f"'no-such-lmp' not found.*set {runner.EXECUTABLE_ENV}"):
        runner.executable()
