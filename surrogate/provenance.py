"""Which checkpoint made an output: every metrics file, rollout and test table names its model by the short
SHA-256 of the checkpoint file, an ensemble by its members' digests joined by '+' in the order given.

Pure file hashing: reading or checking a name imports neither torch nor the model.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

__all__ = ["as_paths", "digest", "file_digest", "label"]


def file_digest(path: str | Path) -> str:
    """Short SHA-256 (12 hex digits) of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()[:12]


def as_paths(paths: Path | str | Sequence[Path | str]) -> list[Path]:
    """One checkpoint path or several, as a non-empty list."""
    out = [Path(paths)] if isinstance(paths, str | Path) else [Path(p) for p in paths]
    if not out:
        raise ValueError("no checkpoint given")
    return out


def digest(paths: Path | str | Sequence[Path | str]) -> str:
    """The short SHA-256 of one checkpoint; of several, their digests joined by '+' in the order given (an
    ensemble is named by its models)."""
    return "+".join(file_digest(p) for p in as_paths(paths))


def label(paths: Path | str | Sequence[Path | str]) -> str:
    """The checkpoint path, or the paths of an ensemble separated by spaces (as recorded in outputs)."""
    return " ".join(str(p) for p in as_paths(paths))
