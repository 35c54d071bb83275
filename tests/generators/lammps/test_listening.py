"""No LAMMPS process listens on the network: a real job (settling, then a recorded run on one rank and on two),
with the listening sockets of this test's processes polled every 10 ms throughout.

One rank is an isolated OpenMPI singleton (runner.ENGINE_ENV), which used to start a daemon (orted) and a TCP
transport listening on 0.0.0.0 and [::]; mpirun, whose runtime binds its out-of-band listener to every
address, runs in a network namespace of its own whose only interface is the loopback one (netns.py). The
test's own namespace must see no new listening socket at all, on any address, loopback included.
"""

import os
import re
import subprocess
import threading
from pathlib import Path

import pytest

from generators import config, engine, sweep
from generators.lammps import netns, runner
from generators.scenes import meteorite

pytestmark = pytest.mark.engine


def _parent(pid: int) -> int:
    return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])


def _descends_from_this_test(pid: int) -> bool:
    """Whether process ``pid`` is this test process or one it started (directly or not)."""
    while pid > 1:
        if pid == os.getpid():
            return True
        try:
            pid = _parent(pid)
        except (OSError, ValueError, IndexError):
            return False
    return False


def listeners() -> set[tuple[str, str, str]]:
    """(protocol, local address, process) of every listening TCP socket and bound UDP socket held by this
    test's processes in its own network namespace (ss -ltnup); other programs are not this test's business."""
    out = subprocess.run(["ss", "-ltnupH"], capture_output=True, text=True, check=True).stdout
    held = set()
    for line in out.splitlines():
        pids = [int(p) for p in re.findall(r"pid=(\d+)", line)]
        if line.strip() and any(_descends_from_this_test(p) for p in pids):
            fields = line.split()
            held.add((fields[0], fields[4], ",".join(re.findall(r'"([^"]+)"', line))))
    return held


def processes() -> set[tuple[str, str, frozenset]]:
    """(name, network namespace, its interfaces) of every process this test started that is alive now."""
    ours, found = os.readlink("/proc/self/ns/net"), set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if not _descends_from_this_test(int(entry.name)):
                continue
            name, ns = (entry / "comm").read_text().strip(), os.readlink(entry / "ns" / "net")
            interfaces = frozenset(line.split(":")[0].strip() for line in (entry / "net" / "dev").read_text()
                                   .splitlines()[2:])
        except OSError:                     # it ended meanwhile
            continue
        found.add((name, "this test's" if ns == ours else ns, interfaces))
    return found


def test_no_lammps_process_listens_on_one_rank_or_two(tmp_path):
    """Settling and a recorded run on one rank, the same run on two: no socket of this test's processes listens
    in its namespace during any of them (before: lmp on 0.0.0.0:1024 and [::]:1024, orted on three ports, mpirun
    on 0.0.0.0, [::] and 127.0.0.1); the two-rank run's processes were seen in a namespace whose only
    interface is lo."""
    cfg = config.load({"scale": "ci", "meteorite": {"bed_depth": 30.0, "frames": 30}})["meteorite"]
    row = sweep.build("meteorite", cfg).iloc[0].to_dict()
    two_ranks = runner.mpirun_path() is not None
    before, seen, procs, done = listeners(), set(), set(), threading.Event()

    def poll():
        while not done.is_set():
            seen.update(listeners() - before)
            procs.update(processes())
            done.wait(0.01)

    poller = threading.Thread(target=poll)
    poller.start()
    try:
        engine.prepare(meteorite.SCENE, "lammps", meteorite.SCENE.packings(cfg)[0], tmp_path / "packing")
        engine.simulate(meteorite.SCENE, row, tmp_path / "packing", tmp_path / "raw1")
        if two_ranks and netns.problem() is None:
            engine.simulate(meteorite.SCENE, row, tmp_path / "packing", tmp_path / "raw2", ranks=2)
    finally:
        done.set()
        poller.join()
    assert seen == set(), f"sockets listening during the LAMMPS job: {sorted(seen)}"
    assert any(name == "lmp" and ns == "this test's" for name, ns, _ in procs), procs    # the poll saw the runs
    if not two_ranks:
        pytest.skip("mpirun is not on PATH (Debian's openmpi-bin): the 2-rank run was not tried")
    if netns.problem() is not None:           # refused before anything starts: nothing can listen
        with pytest.raises(runner.MpiUnisolated, match="allowed here: 1"):
            engine.simulate(meteorite.SCENE, row, tmp_path / "packing", tmp_path / "raw2", ranks=2)
        return
    isolated = {(name, ns, interfaces) for name, ns, interfaces in procs if ns != "this test's"}
    assert {"mpirun", "lmp"} <= {name for name, _, _ in isolated}, procs
    assert {interfaces for _, _, interfaces in isolated} == {frozenset({"lo"})}
    assert runner.ranks_of(tmp_path / "raw2" / "log.lammps") == 2
