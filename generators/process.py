"""Run an engine process and measure it: exit status, wall time and the child's own peak memory."""

from __future__ import annotations

import os
import subprocess
import time
from pathlib import Path


def run_measured(cmd: list[str], cwd: Path, env: dict, stdout, stderr) -> tuple[int, float, float]:
    """(exit status, wall seconds, peak resident MB of this child alone, not the session's) of ``cmd``."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=stdout, stderr=stderr, text=True)
    _, status, usage = os.wait4(proc.pid, 0)
    return os.waitstatus_to_exitcode(status), time.perf_counter() - start, usage.ru_maxrss / 1024
