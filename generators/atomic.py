"""Atomic file output: write under a temporary name in the same folder, then rename.

:func:`atomic_path` stages one output, :func:`atomic_outputs` several that appear together or not at all, and
:func:`h5_file` builds an HDF5 file in memory so that HDF5 itself never writes to the disk. A write that fails (a
full disk, a file-size limit, a plot that raises) leaves what was at the paths before untouched and no temporary;
an OSError of the write is raised as an :class:`OutputError` naming the output's path (not its temporary) and the
cause. An existing folder is never deleted to make room for a file, nor a file for a folder; a folder output
replaces a folder only if that folder looks like an earlier output of the same kind (:func:`replaceable`).
"""

from __future__ import annotations

import contextlib
import errno
import glob
import os
import re
import shutil
from collections.abc import Iterator
from pathlib import Path

#: errnos of a write that did not fit: raised by the write itself, often without a file name
WRITE_ERRNOS = frozenset({errno.EFBIG, errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EROFS})


class OutputError(OSError):
    """An output that could not be written, or may not replace what is at its path: ``path`` and ``why``."""

    def __init__(self, path: str | os.PathLike, why: str):
        super().__init__(f"{path}: {why}")
        self.path, self.why = Path(path), why


class _Staged:
    """One output being written: its temporary sibling (the suffix kept: writers infer formats from it)."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self.tmp = self.path.with_name(f".{self.path.stem}.tmp-{os.getpid()}{self.path.suffix}")
        self.made = _make_parents(self.path.parent)
        remove_stale(self.path)
        _remove(self.tmp)

    @contextlib.contextmanager
    def naming(self) -> Iterator[Path]:
        """Yield the temporary; an OSError of writing it is raised as an OutputError naming the path."""
        try:
            yield self.tmp
        except OutputError as exc:
            if exc.path != self.tmp:
                raise
            raise OutputError(self.path, exc.why) from exc
        except OSError as exc:
            where = self._where(exc)
            if where is None:
                raise
            raise OutputError(where, f"cannot be written: {exc.strerror or exc}") from exc

    def _where(self, exc: OSError) -> Path | None:
        """The output an OSError is a failed write of (the path, or a file in a folder output), or None."""
        if exc.filename is None:
            return self.path if exc.errno in WRITE_ERRNOS else None
        name, tmp = (Path(os.path.abspath(p)) for p in (os.fsdecode(exc.filename), self.tmp))
        if name == tmp or tmp in name.parents:
            return self.path / name.relative_to(tmp)
        return None

    def check(self) -> None:
        """Refuse to put a file where a folder is, a folder where a file is, or a folder over a foreign one."""
        if not os.path.lexists(self.tmp):
            raise OutputError(self.path, "the writer made no output")
        if self.path.is_symlink() or not self.path.exists():
            return
        new_dir, old_dir = self.tmp.is_dir() and not self.tmp.is_symlink(), self.path.is_dir()
        if old_dir and not new_dir:
            raise OutputError(self.path, "is an existing folder, which a file output does not replace: give a file "
                                         "path, or move the folder away")
        if new_dir and not old_dir:
            raise OutputError(self.path, "is an existing file, which a folder output does not replace: give another "
                                         "path, or move the file away")
        if new_dir and not replaceable(self.path, self.tmp):
            held = sorted(os.listdir(self.path))
            raise OutputError(self.path, "is an existing folder that does not hold an earlier output of this kind "
                                         f"({', '.join(held[:4])}{', ...' if len(held) > 4 else ''}); it is not "
                                         "replaced: give another path, or move the folder away")

    def commit(self) -> None:
        """Rename the temporary onto the path (an old folder is moved aside first and removed after)."""
        try:
            if not (self.path.is_dir() and not self.path.is_symlink()):
                os.replace(self.tmp, self.path)
                return
            old = _old_name(self.path, os.getpid())
            _remove(old)
            os.rename(self.path, old)
            try:
                os.rename(self.tmp, self.path)
            except OSError:
                os.rename(old, self.path)
                raise
            _remove(old)
        except OSError as exc:
            raise OutputError(self.path, f"cannot be renamed into place: {exc.strerror or exc}") from exc

    def discard(self) -> None:
        """Remove the temporary, and the folders made for it if the path was not written and they are empty."""
        _remove(self.tmp)
        if not os.path.lexists(self.path):
            for folder in self.made:
                with contextlib.suppress(OSError):
                    folder.rmdir()


class Outputs:
    """The outputs of one :func:`atomic_outputs` block: call it with a path to stage that output."""

    def __init__(self) -> None:
        self.staged: list[_Staged] = []

    @contextlib.contextmanager
    def __call__(self, path: str | os.PathLike) -> Iterator[Path]:
        """Yield the temporary to write ``path``'s output to (renamed onto ``path`` when the whole group ends)."""
        if any(Path(path) == earlier.path for earlier in self.staged):
            raise OutputError(path, "is given for two outputs of one command; give each its own path")
        staged = _Staged(path)
        self.staged.append(staged)
        with staged.naming() as tmp:
            yield tmp


@contextlib.contextmanager
def atomic_outputs() -> Iterator[Outputs]:
    """Stage several outputs (``with output(path) as tmp: ...`` for each) that are renamed into place together
    when the block ends, each checked first; if anything in the block fails, none of them is written and what was
    at their paths stays as it was."""
    outputs = Outputs()
    try:
        yield outputs
        for staged in outputs.staged:
            staged.check()
        for staged in outputs.staged:
            staged.commit()
    finally:
        for staged in reversed(outputs.staged):
            staged.discard()


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary sibling of ``path``; rename it onto ``path`` only if the block succeeds.

    Works for files and folders. A failure leaves what was at ``path`` and removes the temporary; a process killed
    before the rename (SIGKILL) leaves its temporary, which the next write of ``path`` removes (its pid is gone).
    """
    with atomic_outputs() as output, output(path) as tmp:
        yield tmp


def replaceable(old: Path, new: Path) -> bool:
    """Whether the folder ``old`` may be replaced by the folder ``new``: ``old`` is empty, or each of its entries
    has the name of one of ``new``'s, digits aside (an earlier output of the same kind, e.g. other frames)."""
    def shape(name: str) -> str:
        return re.sub(r"\d+", "#", name)
    names = {shape(n) for n in os.listdir(new)}
    return all(shape(n) in names for n in os.listdir(old))


@contextlib.contextmanager
def h5_file(tmp: Path) -> Iterator:
    """An HDF5 file built in memory and written to ``tmp`` in one plain write when the block succeeds.

    HDF5 never writes to the disk itself, so a full disk or a file-size limit is an OSError of that one write
    (which :func:`atomic_path` names), never an HDF5 error stack in the middle of a flush or a crash at close."""
    import h5py
    with h5py.File(f"{tmp.name}-in-memory", "w", driver="core", backing_store=False) as f:
        yield f
        f.flush()
        image = f.id.get_file_image()
    with open(tmp, "wb") as fh:
        fh.write(image)


def _make_parents(folder: Path) -> list[Path]:
    """Make ``folder`` and its missing parents; return those made, deepest first."""
    missing = []
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    if missing:
        missing[0].mkdir(parents=True, exist_ok=True)
    return missing


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _old_name(path: Path, pid: int) -> Path:
    return path.with_name(f".{path.stem}.old-{pid}{path.suffix}")


def _dead_pid(name: str, prefix: str, suffix: str) -> bool:
    pid = name[len(prefix):len(name) - len(suffix) or None]
    return pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid))


def remove_stale(path: Path) -> list[Path]:
    """Remove the temporaries of ``path`` left by killed writers (their pid no longer runs); return them. An old
    folder a killed writer had moved aside is put back if ``path`` is missing, else removed."""
    stale = []
    for kind, settle in (("tmp", _remove), ("old", lambda old: _restore(old, path))):
        prefix = f".{path.stem}.{kind}-"
        for found in path.parent.glob(f"{glob.escape(prefix)}*{glob.escape(path.suffix)}"):
            if _dead_pid(found.name, prefix, path.suffix):
                settle(found)
                stale.append(found)
    return stale


def _restore(old: Path, path: Path) -> None:
    if os.path.lexists(path):
        _remove(old)
    else:
        os.rename(old, path)


def _remove(p: Path) -> None:
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p)
    elif p.exists() or p.is_symlink():
        p.unlink()

