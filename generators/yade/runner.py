"""Run Debian's ``yade -n -x`` (no GUI, exit when done, one thread) on graphdem's YADE script.

YADE's launcher opens two servers when it runs as a program: a Python prompt (port 9000) and an
XML-RPC info server (port 21000), on every interface, the prompt's cookie printed to the log. graphdem
needs neither, so the launcher is run by its own interpreter under another module name (``LAUNCH``):
the same option parsing, engine and script execution, without the servers (YADE's launcher starts them
only under ``__main__``). Nothing listens on any socket while a YADE job runs (tested).
"""

from __future__ import annotations

import functools
import json
import os
import re
import shlex
import shutil
import subprocess
from importlib import resources
from pathlib import Path

import numpy as np

from generators.process import run_measured
from generators.record import EngineRun

EXECUTABLE_ENV = "GRAPHDEM_YADE"
SCRIPT = "graphdem_yade.py"


class YadeError(RuntimeError):
    """YADE exited with an error; the message holds the end of its log."""



def executable() -> str:
    exe = os.environ.get(EXECUTABLE_ENV, "yade")
    path = shutil.which(exe)
    if path is None:
        raise FileNotFoundError(f"YADE executable {exe!r} not found: install Debian's `yade` package (make install) "
                                f"or set {EXECUTABLE_ENV} to its path")
    return path


# YADE's launcher (sys.argv[2]) imported as a module, not run as __main__: it parses its options, sets the
# threads and loads YADE, but starts no server and no session; then the script (sys.argv[1]) runs in its
# namespace with the arguments the launcher leaves, as the launcher's own session would run it.
LAUNCH = ("import runpy, sys; script = sys.argv.pop(1); sys.argv = sys.argv[1:]; "
          "ns = runpy.run_path(sys.argv[0], run_name='yade_without_servers'); sys.argv[0] = script; "
          "exec(compile(open(script).read(), script, 'exec'), ns)")


def interpreter(exe: str) -> list[str]:
    """The command YADE's launcher ``exe`` names on its first line (Debian: /usr/bin/python3.x)."""
    with open(exe, "rb") as fh:
        first = fh.readline().decode(errors="replace").strip()
    if not first.startswith("#!") or "python" not in first:
        raise YadeError(f"{exe} is not YADE's Python launcher (first line {first!r}); set {EXECUTABLE_ENV} to it")
    return shlex.split(first[2:])


def version() -> str:
    return _version(executable())


@functools.cache
def _version(path: str) -> str:
    """`yade --version` once per executable and process (each call starts YADE)."""
    out = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=120).stdout
    match = re.search(r"Yade version:\s*(\S+)", out)
    return match.group(1) if match else "unknown"


def run(job: dict, workdir: Path, name: str, threads: int = 1) -> tuple[dict, EngineRun]:
    """Write ``job`` to workdir/<name>.json, run the script on it on ``threads`` OpenMP threads (YADE's
    ``-j``), return its arrays and the run."""
    if int(threads) < 1:
        raise ValueError(f"YADE threads = {threads!r}: a positive number of threads")
    workdir = Path(workdir).resolve()        # yade runs inside workdir: every path it is given is absolute
    script = workdir / SCRIPT
    script.write_text(resources.files("generators.yade").joinpath("scripts", SCRIPT).read_text())
    out = workdir / f"{name}.npz"
    (workdir / f"{name}.json").write_text(json.dumps({**job, "out": str(out)}))
    exe = executable()
    cmd = [*interpreter(exe), "-c", LAUNCH, SCRIPT, exe, "-n", "-x", "-j", str(int(threads)), SCRIPT, f"{name}.json"]
    # Debian's python runs yade: the pipeline's virtual environment must not leak into it
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH", "PYTHONHOME")}
    env.update(OMP_NUM_THREADS=str(int(threads)), DISPLAY="")
    log = workdir / f"{name}.log"
    with open(log, "w") as fh:
        code, wall, rss = run_measured(cmd, workdir, env, fh, subprocess.STDOUT)
    if code != 0 or not out.is_file():
        tail = log.read_text()[-1500:]
        raise YadeError(f"YADE {name} run failed with exit status {code} in {workdir}: ...{tail}")
    with np.load(out) as data:
        arrays = {k: data[k] for k in data.files}
    report = json.loads(Path(str(out) + ".json").read_text())
    return arrays, EngineRun(engine="yade", version=version(), command=shlex.join(cmd), wall_time=wall,
                             max_rss_mb=rss, threads=int(threads), notes=report)
