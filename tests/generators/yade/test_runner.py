"""YADE run headless: no server is ever started, no socket listens while a job runs, and two jobs side by
side agree."""

import json
import os
import re
import subprocess
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from generators import collision, contact, dem
from generators.yade import driver

pytestmark = pytest.mark.engine


def test_two_jobs_side_by_side_start_no_server_and_agree(tmp_path):
    """Neither yade process starts its TCP prompt or XML-RPC server, neither holds a listening socket during
    or after its run, and the concurrent runs give the same answer as each other."""
    c = dem.Contact(young=5.0e7, kn=2.0e5, kt_over_kn=0.3, restitution=0.5, friction=0.5)
    setup = collision.collision_setup(c, 0.004, 2650.0, 3, 0.05 * contact.stable_time_step(
        contact.sphere_mass(2650.0, 0.004), c.kn), 0.05)
    dirs = [tmp_path / "a", tmp_path / "b"]
    for d in dirs:
        d.mkdir()
    with ThreadPoolExecutor(2) as pool:
        results = list(pool.map(lambda d: driver.run_recording(setup, d), dirs))
    (frames_a, run_a), (frames_b, run_b) = results
    assert (frames_a.position == frames_b.position).all()
    for run in (run_a, run_b):
        assert run.notes["servers_closed"] == 0
        assert run.notes["listening_sockets"] == []
    # YADE's own /tmp/yade-XXXXXX (one per process; the script's report names it) is not left behind
    temp_dirs = [json.loads((d / "record.npz.json").read_text())["yade_temp_dir"] for d in dirs]
    assert temp_dirs[0] != temp_dirs[1]
    for temp_dir in temp_dirs:
        assert Path(temp_dir).name.startswith("yade-")
        assert not Path(temp_dir).exists()


def test_a_failing_job_leaves_no_temporary_directory(tmp_path):
    """A job YADE's script cannot run fails with YadeError naming the log's end, and the script still removes
    the /tmp/yade-XXXXXX directory YADE made for it (named in the log)."""
    from generators.yade import runner
    with pytest.raises(runner.YadeError, match="exit status"):
        runner.run({"mode": "no-such-mode"}, tmp_path, "bad")
    log = (tmp_path / "bad.log").read_text()
    found = re.search(r"YADE's temporary directory (\S+)", log)
    assert found, log[-500:]
    assert Path(found.group(1)).name.startswith("yade-")
    assert not Path(found.group(1)).exists()


def _descends_from_this_test(pid: int) -> bool:
    """Whether process ``pid`` is this test process or one it started (directly or not)."""
    while pid > 1:
        if pid == os.getpid():
            return True
        try:
            pid = int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])   # the parent's pid
        except (OSError, ValueError, IndexError):
            return False
    return False


def listeners() -> set[tuple[str, str]]:
    """(local address, process) of every listening TCP socket held by this test's processes (ss -ltnp); other
    programs on the machine are not this test's business."""
    out = subprocess.run(["ss", "-ltnpH"], capture_output=True, text=True, check=True).stdout
    held = set()
    for line in out.splitlines():
        pids = [int(p) for p in re.findall(r"pid=(\d+)", line)]
        if line.strip() and any(_descends_from_this_test(p) for p in pids):
            held.add((line.split()[3], ",".join(re.findall(r'"([^"]+)"', line))))
    return held


def test_a_shear_job_opens_no_port_while_it_runs(tmp_path):
    """A real YADE shear settle and sim, with the listening sockets polled every 10 ms throughout: no socket
    appears that was not there before (YADE's launcher used to listen on 0.0.0.0:9000 and :21000 for up to a
    second), and the job's log holds no auth cookie."""
    from generators import config, engine, sweep
    from generators.scenes import shear
    cfg = config.load({"scale": "ci", "shear": {"radius": [0.008, 0.01], "wall_radius": 0.008, "frames": 3,
                                                   "model": {"history": 2}}})["shear"]
    before, seen, done = listeners(), set(), threading.Event()

    def poll():
        while not done.is_set():
            seen.update(listeners() - before)
            done.wait(0.01)

    poller = threading.Thread(target=poll)
    poller.start()
    try:
        engine.prepare(shear.SCENE, "yade", shear.SCENE.packings(cfg)[0], tmp_path / "packing")
        engine.simulate(shear.SCENE, sweep.build("shear", cfg).iloc[0].to_dict(), tmp_path / "packing",
                        tmp_path / "raw")
    finally:
        done.set()
        poller.join()
    assert seen == set(), f"sockets opened during the YADE job: {sorted(seen)}"
    logs = "".join(p.read_text(errors="replace") for p in tmp_path.rglob("*.log"))
    assert logs and "cookie" not in logs.lower() and "TCP python prompt" not in logs
