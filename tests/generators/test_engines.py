"""The engine registry: each engine's driver, how it takes more cores, and the first refusal of MPI ranks."""

import types

import pytest

from generators import engines
from generators.lammps import runner


def test_each_engine_takes_cores_its_own_way():
    assert engines.names() == list(engines.NAMES)
    assert engines.driver("lammps").__name__ == "generators.lammps.driver"
    assert engines.execution("lammps", 4) == (4, 1)             # MPI ranks of one thread
    assert engines.execution("yade", 4) == (1, 4)               # threads of one process
    assert runner.LammpsError in engines.errors()
    with pytest.raises(ValueError, match="unknown engine 'dune'; known: lammps, yade"):
        engines.driver("dune")


def test_a_driver_of_an_unknown_parallel_kind_is_refused(monkeypatch):
    monkeypatch.setattr(engines, "driver", lambda name: types.SimpleNamespace(PARALLEL="gpus"))
    with pytest.raises(ValueError, match="the lammps driver's PARALLEL = 'gpus'; allowed: ranks, threads"):
        engines.takes_ranks("lammps")


def test_ranks_are_refused_by_the_engine_that_takes_them(monkeypatch, tmp_path):
    assert engines.ranks_problem(1) is None
    monkeypatch.setenv(runner.MPIRUN_ENV, str(tmp_path / "no-mpirun"))
    assert engines.ranks_problem(3) == engines.driver("lammps").ranks_problem(3)
    assert "mpirun -np 3" in engines.ranks_problem(3)
