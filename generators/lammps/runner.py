"""Run the LAMMPS executable on an input deck (generators/lammps/deck.py): one process, or ``ranks`` MPI
ranks on this host under OpenMPI's ``mpirun`` (docs/architecture.md, "LAMMPS under MPI").

Under MPI every rank owns a slab of the box (LAMMPS' domain decomposition) and holds copies of the
particles within the pair cutoff of its slab (ghosts; ``comm_modify vel yes`` gives them velocities, as
the granular contact needs): the same deck, written for one rank, runs on any number of them. Forces
are summed in another order there, so a run on N ranks is not bitwise equal to a serial one.

No LAMMPS process listens on any interface of this host: one rank runs as an isolated OpenMPI singleton that
opens no listening socket (ENGINE_ENV), and ``mpirun``, whose runtime listens on every address, runs in a
network namespace of its own whose only interface is the loopback one (netns.py).
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import tempfile
from pathlib import Path

from generators.lammps import io, netns
from generators.process import run_measured
from generators.record import EngineRun

EXECUTABLE_ENV = "GRAPHDEM_LMP"
MPIRUN_ENV = "GRAPHDEM_MPIRUN"

# OpenMPI on this host only: the ranks exchange data through shared memory (btl self,vader; the ob1
# messaging layer, so no UCX or fabric library probes a network), the runtime talks to its ranks over the
# loopback interface, and every rank gets a slot on localhost (the caller, e.g. Snakemake's `threads:`,
# decides how many cores a job may use). Ranks are not pinned to cores: two runs side by side would
# otherwise be pinned to the same ones. A rank waiting for another yields its core (mpi_yield_when_idle)
# rather than spinning on it: on a machine with other work, the spinning rank took the core the rank it
# waited for needed (a ci meteorite run on 2 ranks beside other jobs: 2-5 s of loop time spinning, 0.2-0.7 s
# yielding). OpenMPI 4.1's launcher binds its out-of-band listener to every address whatever
# oob_tcp_if_include says, so mpirun runs in a network namespace of its own whose only interface is the
# loopback one (netns.py): nothing it listens on is reachable from outside it.
MPI_OPTIONS = ("--bind-to", "none", "--mca", "mpi_yield_when_idle", "1", "--mca", "pml", "ob1",
               "--mca", "btl", "self,vader", "--mca", "oob_tcp_if_include", "lo", "--mca", "btl_tcp_if_include", "lo")

# The environment of every LAMMPS process, one rank or more (OpenMPI reads OMPI_MCA_* as --mca options). One
# rank is an OpenMPI singleton: isolated, it starts no supporting daemon (orted, which listened on every
# address); with btl self,vader it opens no TCP transport (which listened on port 1024 of every address). hwloc
# does not look for X displays (its gl component tried 127.0.0.1:6000-6009). None of these changes a result.
ENGINE_ENV = {"OMP_NUM_THREADS": "1", "OMPI_MCA_ess_singleton_isolated": "1", "OMPI_MCA_pml": "ob1",
              "OMPI_MCA_btl": "self,vader", "HWLOC_COMPONENTS": "-gl"}


class LammpsError(RuntimeError):
    """LAMMPS exited with an error; ``step`` is the last thermo step it printed."""

    def __init__(self, message: str, step: int):
        self.step = step
        super().__init__(message)


class MpiUnavailable(FileNotFoundError):
    """More than one rank was asked for and ``mpirun`` is not on PATH."""


class MpiMismatch(RuntimeError):
    """LAMMPS ran on another number of ranks than asked for (an ``lmp`` built without this MPI)."""


class MpiUnisolated(RuntimeError):
    """More than one rank was asked for and this host cannot give ``mpirun`` a network namespace of its own."""


def executable() -> str:
    exe = os.environ.get(EXECUTABLE_ENV, "lmp")
    path = shutil.which(exe)
    if path is None:
        raise FileNotFoundError(
            f"LAMMPS executable {exe!r} not found: install Debian's `lammps` package (make install) "
            f"or set {EXECUTABLE_ENV} to its path")
    return path


def mpirun_path() -> str | None:
    """OpenMPI's launcher (``mpirun``, or ``$GRAPHDEM_MPIRUN``), None where there is none."""
    return shutil.which(os.environ.get(MPIRUN_ENV, "mpirun"))


def mpirun(ranks: int) -> str:
    path = mpirun_path()
    if path is None:
        raise MpiUnavailable(
            f"ranks = {ranks}: LAMMPS on {ranks} MPI ranks needs `mpirun` on PATH (Debian's openmpi-bin, which the "
            f"`lammps` package installs) or {MPIRUN_ENV} set to it; allowed without it: ranks = 1")
    return path


def isolation_problem(ranks: int) -> str | None:
    """Why ``mpirun`` cannot run in a network namespace of its own here, said after "ranks = N" or a config
    key; None where it can (or for one rank, which needs none)."""
    if ranks == 1 or (reason := netns.problem()) is None:
        return None
    return (f"runs LAMMPS under `mpirun -np {ranks}` in a network namespace of its own (OpenMPI's launcher "
            f"listens on every address of its host), and this host cannot make one ({reason}; a container needs "
            f"user namespaces allowed, e.g. --security-opt seccomp=unconfined); allowed here: 1")


def command(ranks: int = 1) -> list[str]:
    """The command line of a run on ``ranks`` ranks: ``lmp`` alone for one (an isolated OpenMPI singleton:
    ENGINE_ENV), else ``mpirun -np N`` on this host (MPI_OPTIONS) in a network namespace of its own
    (netns.py), where it runs as the namespace's root (hence ``--allow-run-as-root``)."""
    if not isinstance(ranks, int) or ranks < 1:
        raise ValueError(f"ranks = {ranks!r}: a positive number of MPI ranks (1: no mpirun)")
    lmp = [executable(), "-in", "in.lammps"]
    if ranks == 1:
        return lmp
    launcher = mpirun(ranks)
    if (problem := isolation_problem(ranks)) is not None:
        raise MpiUnisolated(f"ranks = {ranks} {problem}")
    return netns.command([launcher, "--allow-run-as-root", "-np", str(ranks), "--host", f"localhost:{ranks}",
                          *MPI_OPTIONS, *lmp])


def ranks_of(log: Path) -> int | None:
    """The number of MPI ranks of the last run in a LAMMPS log ("Loop time of ... on N procs ...")."""
    found = re.findall(r"^Loop time of \S+ on (\d+) procs", Path(log).read_text(), re.M) if Path(log).is_file() else []
    return int(found[-1]) if found else None


def run(text: str, workdir: Path, log_name: str = "log.lammps", ranks: int = 1) -> EngineRun:
    """Write ``text`` into ``workdir`` as in.lammps and run it there on ``ranks`` MPI ranks (one thread
    each); the run's command, version, rank count, wall time and peak memory (of the largest process: one
    rank's, under MPI). The driver adds the window timing and step count."""
    workdir = Path(workdir)
    cmd = [*command(ranks), "-log", log_name, "-screen", "none", "-nocite"]
    (workdir / "in.lammps").write_text(text)
    # OpenMPI's session directory in a folder of this run's own: as a namespace's root, a user other than
    # root could not write the one root's runs leave (/tmp/ompi.HOST.0)
    with tempfile.TemporaryDirectory(prefix="graphdem-lmp-") as session, tempfile.TemporaryFile("w+") as out, \
            tempfile.TemporaryFile("w+") as err:
        code, wall, rss = run_measured(cmd, workdir, dict(os.environ, **ENGINE_ENV, TMPDIR=session), out, err)
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read(), err.read()
    log = workdir / log_name
    if code != 0:
        message = io.error_message(log, stderr + stdout) or stderr[-500:]
        raise LammpsError(f"LAMMPS failed ({message})", io.last_step(log))
    used = ranks_of(log)
    if used is not None and used != ranks:
        raise MpiMismatch(f"LAMMPS ran on {used} MPI rank(s), {ranks} asked for: {mpirun_path()} and {executable()} do "
                          f"not belong to the same MPI (a serial `lmp` under mpirun runs {ranks} separate copies)")
    return EngineRun(engine="lammps", version=io.version(log), command=shlex.join(cmd), wall_time=wall,
                     max_rss_mb=rss, ranks=ranks)
