"""Stale Snakemake locks: a run killed with SIGKILL leaves ``.snakemake/locks/`` behind, and the next run in the
same folder would stop with "Directory cannot be locked". The workflow removes them when no other Snakemake
process works in that folder, so the same command resumes (docs/architecture.md, "Safety and failure")."""

from __future__ import annotations

import os
from pathlib import Path


def _ancestors(pid: int) -> set[int]:
    seen = set()
    while pid > 1 and pid not in seen:
        seen.add(pid)
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            break
        pid = int(stat.rsplit(")", 1)[1].split()[1])
    return seen


def is_snakemake(argv: list[str]) -> bool:
    """Whether a command line runs Snakemake, however it was started: its console script (alone or after an
    interpreter and its options, ``python /venv/bin/snakemake``) or the module (``python -X dev -m snakemake``)."""
    args = iter(argv)
    for i, arg in enumerate(args):
        if Path(arg).name == "snakemake":
            return True
        if arg == "-m":
            return next(args, "").split(".")[0] == "snakemake"
        if arg in ("-X", "-W"):           # an interpreter option with a value
            next(args, None)
        elif i > 0 and not arg.startswith("-"):
            return False                  # the script the interpreter runs, and it is not Snakemake
    return False


def working_folders(argv: list[str], cwd: Path) -> set[Path]:
    """The folders a Snakemake command line works in: its current folder and its ``-d``/``--directory`` (which
    it changes into while it starts)."""
    folders = {cwd}
    for i, arg in enumerate(argv):
        if arg in ("-d", "--directory") and i + 1 < len(argv):
            folders.add((cwd / argv[i + 1]).resolve())
        elif arg.startswith("--directory="):
            folders.add((cwd / arg.partition("=")[2]).resolve())
    return folders


def other_snakemake_in(workdir: Path) -> list[int]:
    """Pids of Snakemake processes other than this one (and its ancestors) that work in ``workdir``."""
    workdir, mine, found = Path(workdir).resolve(), _ancestors(os.getpid()), []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) in mine:
            continue
        try:
            argv = [a.decode(errors="replace") for a in (entry / "cmdline").read_bytes().split(b"\0") if a]
            cwd = (entry / "cwd").resolve()
        except OSError:
            continue
        if is_snakemake(argv) and workdir in working_folders(argv, cwd):
            found.append(int(entry.name))
    return found


def remove_stale_locks(workdir: Path) -> list[Path]:
    """Remove ``workdir/.snakemake/locks/*`` when no other Snakemake process works in ``workdir``; return them."""
    locks = sorted((Path(workdir) / ".snakemake" / "locks").glob("*.lock"))
    if not locks or other_snakemake_in(workdir):
        return []
    for lock in locks:
        lock.unlink(missing_ok=True)
    return locks
