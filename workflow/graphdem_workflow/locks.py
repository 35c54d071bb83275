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


def other_snakemake_in(workdir: Path) -> list[int]:
    """Pids of Snakemake processes other than this one (and its ancestors) whose working folder is ``workdir``."""
    workdir, mine, found = Path(workdir).resolve(), _ancestors(os.getpid()), []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) in mine:
            continue
        try:
            argv = (entry / "cmdline").read_bytes().split(b"\0")[:2]
            cwd = (entry / "cwd").resolve()
        except OSError:
            continue
        if any(Path(a.decode(errors="replace")).name == "snakemake" for a in argv) and cwd == workdir:
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
