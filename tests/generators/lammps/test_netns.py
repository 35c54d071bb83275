"""A command in a network namespace of its own: only the loopback interface, up; the same process (pid, exit
status) the caller started; and a host that cannot make one named."""

import subprocess
import sys

import pytest

from generators.lammps import netns

# Inside the namespace: its interfaces (lo, up), a socket bound on 127.0.0.1, the pid, and an exit status of 3.
PROBE = """
import fcntl, os, socket, struct, sys
lines = open("/proc/net/dev").read().splitlines()[2:]
print(",".join(sorted(line.split(":")[0].strip() for line in lines)))
with socket.socket() as s:
    print(struct.unpack("16sH", fcntl.ioctl(s, 0x8913, struct.pack("16sH22x", b"lo", 0))[:18])[1] & 1)
    s.bind(("127.0.0.1", 0))
    print(s.getsockname()[0])
print(os.getpid())
sys.exit(3)
"""


@pytest.fixture
def namespaces():
    if netns.problem() is not None:
        pytest.skip(f"this host cannot make a network namespace: {netns.problem()}")


def test_a_command_sees_only_loopback_up_and_keeps_its_pid_and_status(namespaces):
    proc = subprocess.Popen(netns.command([sys.executable, "-I", "-c", PROBE]), stdout=subprocess.PIPE, text=True)
    out, _ = proc.communicate(timeout=60)
    interfaces, up, bound, pid = out.split()
    assert interfaces == "lo" and up == "1" and bound == "127.0.0.1"
    assert int(pid) == proc.pid and proc.returncode == 3      # exec all along: the caller waits for the command


def test_the_wrapper_needs_a_command():
    done = subprocess.run([sys.executable, "-I", netns.__file__], capture_output=True, text=True)
    assert done.returncode == 1 and "usage: netns.py COMMAND" in done.stderr


def test_a_host_without_unshare_is_named(monkeypatch, tmp_path):
    monkeypatch.setenv("PATH", str(tmp_path))
    assert netns.problem.__wrapped__() == "`unshare` (util-linux) is not on PATH"


def test_a_refused_namespace_is_named_with_unshares_own_words(monkeypatch, tmp_path):
    fake = tmp_path / "unshare"
    fake.write_text("#!/bin/sh\necho 'unshare: unshare failed: Operation not permitted' >&2\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", f"{tmp_path}:/usr/bin:/bin")
    assert netns.problem.__wrapped__() == ("`unshare --net --map-root-user` failed: unshare: unshare failed: "
                                           "Operation not permitted")
