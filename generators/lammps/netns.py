"""Run a command in a network namespace of its own, whose only interface is the loopback one: whatever the
command listens on (OpenMPI's ``mpirun`` binds its out-of-band listener to every address), no other host and
no process outside the namespace can reach it (docs/architecture.md, "LAMMPS under MPI").

``unshare --net --map-root-user`` (util-linux) makes the namespace, as root or as any user the kernel lets
make a user namespace; this file, run as a script (``python -I netns.py CMD ...``: the standard library alone),
brings the namespace's loopback interface up and replaces itself with ``CMD``, so the command keeps the pid,
the exit status and the resource usage the caller waits for. Inside, the command runs as the namespace's root
(the caller's own user outside it).
"""

from __future__ import annotations

import fcntl
import functools
import os
import shutil
import socket
import struct
import subprocess
import sys

SIOCGIFFLAGS, SIOCSIFFLAGS, IFF_UP = 0x8913, 0x8914, 0x1


def command(cmd: list[str]) -> list[str]:
    """``cmd`` run in a network namespace of its own with the loopback interface up."""
    return [shutil.which("unshare") or "unshare", "--net", "--map-root-user", sys.executable, "-I",
            os.path.abspath(__file__), *cmd]


@functools.cache
def problem() -> str | None:
    """Why this host cannot run a command in a namespace of its own (no ``unshare``, user or network
    namespaces refused, as in a container without CAP_SYS_ADMIN); None where it can. Tried once per process."""
    if shutil.which("unshare") is None:
        return "`unshare` (util-linux) is not on PATH"
    try:
        done = subprocess.run(command(["true"]), capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired) as err:
        return f"`unshare --net --map-root-user` failed: {err}"
    if done.returncode != 0:
        said = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])[-1]
        return f"`unshare --net --map-root-user` failed: {said}"
    return None


def loopback_up() -> None:
    """Bring the interface ``lo`` of this process's network namespace up (127.0.0.1 and ::1 appear with it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        request = struct.pack("16sH22x", b"lo", 0)
        flags = struct.unpack("16sH", fcntl.ioctl(sock, SIOCGIFFLAGS, request)[:18])[1]
        fcntl.ioctl(sock, SIOCSIFFLAGS, struct.pack("16sH22x", b"lo", flags | IFF_UP))


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit("usage: netns.py COMMAND [ARGUMENT ...] (run under `unshare --net --map-root-user`)")
    try:
        loopback_up()
    except OSError as err:
        sys.exit(f"netns.py: cannot bring the loopback interface up: {err}")
    os.execvp(sys.argv[1], sys.argv[1:])
