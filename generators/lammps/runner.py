"""Run the LAMMPS executable on an input deck (generators/lammps/deck.py), single-threaded."""

from __future__ import annotations

import os
import shlex
import shutil
import tempfile
from pathlib import Path

from generators.lammps import io
from generators.process import run_measured
from generators.record import EngineRun

EXECUTABLE_ENV = "GRAPHDEM_LMP"


class LammpsError(RuntimeError):
    """LAMMPS exited with an error; ``step`` is the last thermo step it printed."""

    def __init__(self, message: str, step: int):
        self.step = step
        super().__init__(message)



def executable() -> str:
    exe = os.environ.get(EXECUTABLE_ENV, "lmp")
    path = shutil.which(exe)
    if path is None:
        raise FileNotFoundError(
            f"LAMMPS executable {exe!r} not found: install Debian's `lammps` package (make install) "
            f"or set {EXECUTABLE_ENV} to its path")
    return path


def run(text: str, workdir: Path, log_name: str = "log.lammps") -> EngineRun:
    """Write ``text`` into ``workdir`` as in.lammps and run it there, single-threaded; the run's command,
    version, wall time and peak memory (the driver adds the window timing and step count)."""
    workdir = Path(workdir)
    (workdir / "in.lammps").write_text(text)
    cmd = [executable(), "-in", "in.lammps", "-log", log_name, "-screen", "none", "-nocite"]
    env = dict(os.environ, OMP_NUM_THREADS="1")
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        code, wall, rss = run_measured(cmd, workdir, env, out, err)
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read(), err.read()
    log = workdir / log_name
    if code != 0:
        message = io.error_message(log, stderr + stdout) or stderr[-500:]
        raise LammpsError(f"LAMMPS failed ({message})", io.last_step(log))
    return EngineRun(engine="lammps", version=io.version(log), command=shlex.join(cmd), wall_time=wall,
                     max_rss_mb=rss)
