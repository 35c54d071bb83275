"""Running an engine process measured: its exit status, its wall time and its own peak memory, not the caller's."""

import json
import subprocess
import sys

from generators.process import run_measured

ALLOCATE = 200          # MB the measured child touches
CHILD = (f"import time; b = bytearray({ALLOCATE} * 2**20); b[::4096] = b'x' * len(b[::4096]); time.sleep(0.2); "
         "raise SystemExit(3)")


def test_status_wall_time_and_the_child_s_peak_memory(tmp_path):
    # measured from a fresh interpreter that imports nothing else (a small caller: see the test below)
    code = (f"import json, subprocess, sys; from generators.process import run_measured; "
            f"print(json.dumps(run_measured([sys.executable, '-c', {CHILD!r}], {str(tmp_path)!r}, {{}}, "
            f"subprocess.DEVNULL, subprocess.DEVNULL)))")
    status, wall, rss = json.loads(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                                  check=True).stdout)
    assert status == 3
    assert wall >= 0.2
    assert ALLOCATE <= rss < ALLOCATE + 100          # the allocation plus an interpreter


def test_the_child_s_output_goes_where_asked(tmp_path):
    out = tmp_path / "out.txt"
    with out.open("w") as stdout:
        status, wall, _ = run_measured([sys.executable, "-c", "print('hello')"], tmp_path, {}, stdout,
                                       subprocess.DEVNULL)
    assert status == 0 and out.read_text() == "hello\n" and wall > 0
