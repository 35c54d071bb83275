"""One scale per results folder: a run at another scale never silently overwrites a folder's results.

A scene's or public benchmark's folder ``results/<name>/`` records the scale preset it was built at in
``scale.txt`` (written when a run that involves it starts). A later run at another scale is refused before
anything runs, naming the recorded scale and the ways on: keep the other scale in its own working directory
(``snakemake -d``), move the folder aside, or replace it with ``--config overwrite_scale=true``.
"""

from __future__ import annotations

from pathlib import Path

from generators.atomic import atomic_path

STAMP = "scale.txt"


class ScaleConflict(ValueError):
    """A folder holds results of another scale than the run asks for; the message says what to do."""


def recorded(folder: str | Path) -> str | None:
    """The scale ``folder``'s results were built at, or None when it records none."""
    stamp = Path(folder) / STAMP
    return stamp.read_text().strip() or None if stamp.is_file() else None


def check(folder: str | Path, scale: str, overwrite: bool = False) -> None:
    """Raise ScaleConflict when ``folder`` holds results of a scale other than ``scale`` (unless ``overwrite``)."""
    old = recorded(folder)
    if old is None or old == scale or overwrite:
        return
    raise ScaleConflict(
        f"{folder} holds results of scale={old}; this run asks for scale={scale} and would overwrite them. "
        f"Keep both by running the other scale in its own working directory (snakemake -d runs/{scale} ... "
        f"--config scale={scale}), or move {folder} aside; to replace them, add --config overwrite_scale=true.")


def record(folder: str | Path, scale: str) -> None:
    """Write ``folder``'s scale stamp (atomically)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    with atomic_path(folder / STAMP) as tmp:
        tmp.write_text(f"{scale}\n")
