"""Running an engine process measured: its exit status, its wall time and its own peak memory, not the caller's."""

import subprocess
import sys

from generators.process import run_measured

ALLOCATE = 200          # MB the child touches


def test_status_wall_time_and_the_child_s_own_peak_memory(tmp_path):
    code = (f"import time; b = bytearray({ALLOCATE} * 2**20); b[::4096] = b'x' * len(b[::4096]); time.sleep(0.2); "
            "raise SystemExit(3)")
    status, wall, rss = run_measured([sys.executable, "-c", code], tmp_path, {}, subprocess.DEVNULL,
                                     subprocess.DEVNULL)
    assert status == 3
    assert wall >= 0.2
    assert ALLOCATE <= rss < ALLOCATE + 200          # the allocation plus an interpreter, not this process's own


def test_a_small_child_reports_a_small_peak_and_its_output_goes_where_asked(tmp_path):
    out = tmp_path / "out.txt"
    with out.open("w") as stdout:
        status, _, rss = run_measured([sys.executable, "-c", "print('hello')"], tmp_path, {}, stdout,
                                      subprocess.DEVNULL)
    assert status == 0 and out.read_text() == "hello\n" and rss < ALLOCATE
