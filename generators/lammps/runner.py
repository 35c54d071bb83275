"""Run the LAMMPS executable on an input deck (generators/lammps/deck.py), single-threaded."""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from generators.lammps import io

EXECUTABLE_ENV = "GRAPHDEM_LMP"


class LammpsError(RuntimeError):
    """LAMMPS exited with an error; ``step`` is the last thermo step it printed."""

    def __init__(self, message: str, step: int):
        self.step = step
        super().__init__(message)


@dataclass(frozen=True)
class Run:
    command: str
    version: str
    wall_time: float
    max_rss_mb: float = float("nan")     # peak resident memory of the LAMMPS process


def executable() -> str:
    exe = os.environ.get(EXECUTABLE_ENV, "lmp")
    path = shutil.which(exe)
    if path is None:
        raise FileNotFoundError(
            f"LAMMPS executable {exe!r} not found: install Debian's `lammps` package (make install) "
            f"or set {EXECUTABLE_ENV} to its path")
    return path


def run(text: str, workdir: Path, log_name: str = "log.lammps") -> Run:
    """Write ``text`` into ``workdir`` as in.lammps and run it there, single-threaded."""
    workdir = Path(workdir)
    (workdir / "in.lammps").write_text(text)
    cmd = [executable(), "-in", "in.lammps", "-log", log_name, "-screen", "none", "-nocite"]
    env = dict(os.environ, OMP_NUM_THREADS="1")
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        start = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=workdir, env=env, stdout=out, stderr=err, text=True)
        _, status, usage = os.wait4(proc.pid, 0)          # this child's own peak memory, not the session's
        wall = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read(), err.read()
    log = workdir / log_name
    if proc.returncode != 0:
        message = io.error_message(log, stderr + stdout) or stderr[-500:]
        raise LammpsError(f"LAMMPS failed ({message})", io.last_step(log))
    return Run(command=shlex.join(cmd), version=io.version(log), wall_time=wall, max_rss_mb=usage.ru_maxrss / 1024)
