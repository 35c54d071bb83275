"""LAMMPS text dump files, one trajectory per file (``dump ID group custom N file id type x y z ...``; gzipped
``.gz`` too).

A snapshot is ``ITEM: TIMESTEP`` (the step), optionally ``ITEM: UNITS`` and ``ITEM: TIME`` (``dump_modify units
yes`` / ``time yes``), ``ITEM: NUMBER OF ATOMS``, ``ITEM: BOX BOUNDS`` with the boundary flags per axis (``pp``,
``ff``, ``fs``, ``sm``, ...) and one ``lo hi`` line per axis (a triclinic box, whose line names tilt factors, is
refused), and ``ITEM: ATOMS`` with the column names, then one line per atom in any order. The columns used:
``id`` and ``type`` (required), the coordinates ``x y [z]`` (or unwrapped ``xu yu [zu]``, scaled ``xs ys [zs]``,
``xsu ysu [zsu]``), ``radius`` (or ``diameter``) and ``mass`` where present; others (velocities, forces) are
ignored.

Atoms are sorted by id; every snapshot must hold the same atoms with the same type, radius and mass, and the steps
must increase. The trajectory is 2D when the dump has no z column, when z is the same for every atom in every
snapshot, or when dim 2 is given (then z must be constant); dim 3 keeps z. The box is the first snapshot's; it
may change only along a shrink-wrapped axis (flag s or m), where the box spans all snapshots' bounds. An axis with
flags ``pp`` is periodic. Times are the snapshots' ``ITEM: TIME`` where every snapshot has one, else step x dt
(the LAMMPS ``timestep``, given). Values are taken as they are (``units si`` gives SI; other LAMMPS units are
not converted, and the dump's ``ITEM: UNITS`` is kept in the parameters).
"""

from __future__ import annotations

import gzip
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from generators.importers.metadata import Given, ImportRefused
from generators.importers.sims import Source

COORDINATES = (("x", "y", "z"), ("xu", "yu", "zu"), ("xs", "ys", "zs"), ("xsu", "ysu", "zsu"))
SCALED = ("xs", "xsu")
PATTERNS = ("*.dump", "*.dump.gz", "dump.*", "*.lammpstrj", "*.lammpstrj.gz")
AXES = "xyz"


class _Lines:
    """A dump's lines with their numbers, for messages that say where the file is wrong."""

    def __init__(self, path: Path):
        self.path, self.number = path, 0
        opener = gzip.open if path.suffix == ".gz" else open
        self.handle = opener(path, "rt", encoding="utf-8", errors="replace")

    def next(self, what: str) -> str:
        """The next line, inside ``what``; the end of the file there is refused."""
        line = self.handle.readline()
        if not line:
            raise ImportRefused(f"{self.path}: ends inside {what} (truncated?)")
        self.number += 1
        return line.strip()

    def refuse(self, what: str) -> ImportRefused:
        return ImportRefused(f"{self.path}: line {self.number}: {what}")


@dataclass
class Snapshot:
    """One snapshot: its step, time, units, box [3, 2] with flags, column names and values [N, C]."""

    step: int
    time: float | None = None
    units: str | None = None
    box: np.ndarray | None = None
    flags: tuple[str, ...] = ()
    columns: list[str] = field(default_factory=list)
    table: np.ndarray | None = None


def _number(lines: _Lines, kind, what: str):
    text = lines.next(what)
    try:
        return kind(text)
    except ValueError:
        raise lines.refuse(f"{what} must be a {'whole number' if kind is int else 'number'}, got {text!r}") from None


def _box(lines: _Lines, header: str, snap: Snapshot) -> None:
    words = header.split()[3:]
    if any(w in ("xy", "xz", "yz", "abc", "origin") for w in words):
        raise lines.refuse(f"a triclinic box ({header!r}); only orthogonal boxes are read")
    snap.flags = tuple(words) if len(words) == 3 else ()
    try:
        snap.box = np.array([[float(v) for v in lines.next("BOX BOUNDS").split()[:2]] for _ in range(3)])
    except ValueError:
        raise lines.refuse("BOX BOUNDS lines must hold 'lo hi'") from None
    if snap.box.shape != (3, 2):
        raise lines.refuse("BOX BOUNDS lines must hold 'lo hi'")


def _atoms(lines: _Lines, header: str, snap: Snapshot, n: int) -> None:
    snap.columns = header.split()[2:]
    rows = [lines.next("ATOMS") for _ in range(n)]
    try:
        values = np.array(" ".join(rows).split(), dtype=np.float64)
    except ValueError:
        raise lines.refuse(f"the atoms of step {snap.step} hold a value that is not a number") from None
    if values.size != n * len(snap.columns):
        raise lines.refuse(f"the {n} atoms of step {snap.step} hold {values.size} values, not {len(snap.columns)} "
                           f"each ({' '.join(snap.columns)})")
    snap.table = values.reshape(n, len(snap.columns))


def snapshots(path: Path) -> Iterator[Snapshot]:
    """Every snapshot of a dump file, in the file's order."""
    lines = _Lines(path)
    snap, n = None, None
    with lines.handle:
        while line := lines.handle.readline():
            lines.number += 1
            item = line.strip()
            if not item:
                continue
            if item == "ITEM: TIMESTEP":
                snap, n = Snapshot(step=_number(lines, int, "TIMESTEP")), None
            elif snap is None:
                raise lines.refuse(f"expected 'ITEM: TIMESTEP', got {item[:60]!r}; not a LAMMPS text dump")
            elif item == "ITEM: TIME":
                snap.time = _number(lines, float, "TIME")
            elif item == "ITEM: UNITS":
                snap.units = lines.next("UNITS")
            elif item == "ITEM: NUMBER OF ATOMS":
                n = _number(lines, int, "NUMBER OF ATOMS")
            elif item.startswith("ITEM: BOX BOUNDS"):
                _box(lines, item, snap)
            elif item.startswith("ITEM: ATOMS") and n is not None and snap.box is not None:
                _atoms(lines, item, snap, n)
                yield snap
                snap = None
            else:
                raise lines.refuse(f"unexpected {item[:60]!r} (a snapshot is TIMESTEP, NUMBER OF ATOMS, BOX BOUNDS, "
                                   f"ATOMS)")
    if snap is not None:
        raise ImportRefused(f"{path}: ends inside the snapshot of step {snap.step} (truncated?)")


def _layout(columns: list[str], path: Path) -> dict:
    """Where each quantity is among ``columns``: id, type, coordinates (scaled or not), radius (x 0.5 for a
    diameter) and mass."""
    if "id" not in columns or "type" not in columns:
        raise ImportRefused(f"{path}: the ATOMS columns ({' '.join(columns)}) must include id and type (dump ... "
                            f"custom N file id type x y z ...)")
    coords = next(([columns.index(c) for c in names if c in columns] for names in COORDINATES
                   if names[0] in columns and names[1] in columns), None)
    if coords is None:
        raise ImportRefused(f"{path}: the ATOMS columns ({' '.join(columns)}) hold no coordinates; allowed: "
                            f"{', '.join(' '.join(c) for c in COORDINATES)}")
    radius = ("radius", 1.0) if "radius" in columns else ("diameter", 0.5) if "diameter" in columns else None
    return {"id": columns.index("id"), "type": columns.index("type"), "coords": coords,
            "scaled": columns[coords[0]] in SCALED, "radius": radius and (columns.index(radius[0]), radius[1]),
            "mass": columns.index("mass") if "mass" in columns else None}


def _per_atom(snap: Snapshot, layout: dict) -> dict:
    """A snapshot's atoms sorted by id: ids, types, positions [N, 2|3], radius and mass (None where absent)."""
    table = snap.table[np.argsort(snap.table[:, layout["id"]], kind="stable")]
    position = table[:, layout["coords"]]
    if layout["scaled"]:
        box = snap.box[: position.shape[1]]
        position = box[:, 0] + position * (box[:, 1] - box[:, 0])
    radius = layout["radius"]
    return {"id": table[:, layout["id"]], "type": table[:, layout["type"]], "position": position,
            "radius": None if radius is None else table[:, radius[0]] * radius[1],
            "mass": None if layout["mass"] is None else table[:, layout["mass"]]}


def _same_atoms(first: dict, atoms: dict, snap: Snapshot, path: Path) -> None:
    if atoms["id"].shape != first["id"].shape or not np.array_equal(atoms["id"], first["id"]):
        raise ImportRefused(f"{path}: step {snap.step} holds other atoms ({len(atoms['id'])}) than the first "
                            f"snapshot ({len(first['id'])}); a trajectory keeps its particles")
    for key in ("type", "radius", "mass"):
        if first[key] is not None and not np.array_equal(atoms[key], first[key]):
            raise ImportRefused(f"{path}: the atoms' {key} at step {snap.step} differs from the first snapshot's; a "
                                f"trajectory's particles keep theirs")


def _fixed_box(boxes: np.ndarray, flags: tuple[str, ...], path: Path) -> np.ndarray:
    """The box [3, 2]: the first snapshot's, or on a shrink-wrapped axis the span of all snapshots' bounds."""
    box = boxes[0].copy()
    for axis in range(3):
        if np.all(boxes[:, axis] == boxes[0, axis]):
            continue
        if flags and set(flags[axis]) & {"s", "m"}:
            box[axis] = boxes[:, axis, 0].min(), boxes[:, axis, 1].max()
        else:
            raise ImportRefused(f"{path}: the box changes along {AXES[axis]} (flags "
                                f"{flags[axis] if flags else 'not given'}); a trajectory has a fixed box (only a "
                                f"shrink-wrapped axis, s or m, may change)")
    return box


def _dim(position: np.ndarray, items: Given, path: Path) -> int:
    """2 or 3 (module docstring)."""
    if position.shape[2] == 2:
        return 2
    flat = bool(np.all(position[:, :, 2] == position[0, 0, 2]))
    dim = items.get("dim") or (2 if flat else 3)
    if dim == 2 and not flat:
        raise ImportRefused(f"{path}: {items.where('dim')} says dim 2, but z varies from "
                            f"{position[:, :, 2].min():.6g} to {position[:, :, 2].max():.6g}")
    return dim


def _collect(path: Path) -> tuple[list[Snapshot], list[dict], dict]:
    """Every snapshot (without its table) and its atoms sorted by id, checked against the first."""
    snaps, atoms, layout = [], [], None
    for snap in snapshots(path):
        if layout is None:
            layout = _layout(snap.columns, path)
        elif snap.columns != snaps[0].columns:
            raise ImportRefused(f"{path}: step {snap.step} has the columns {' '.join(snap.columns)}, the first "
                                f"snapshot {' '.join(snaps[0].columns)}")
        if snaps and snap.step <= snaps[-1].step:
            raise ImportRefused(f"{path}: step {snap.step} follows step {snaps[-1].step}; the steps must increase "
                                f"(two runs appended to one dump?)")
        atoms.append(_per_atom(snap, layout))
        if len(np.unique(atoms[-1]["id"])) != len(atoms[-1]["id"]):
            raise ImportRefused(f"{path}: step {snap.step} lists an atom id twice")
        _same_atoms(atoms[0], atoms[-1], snap, path)
        snap.table = None
        snaps.append(snap)
    if len(snaps) < 2:
        raise ImportRefused(f"{path}: {len(snaps)} snapshot(s); a trajectory needs at least 2")
    return snaps, atoms, layout


def source(path: Path, items: Given) -> Source:
    """One dump file as a :class:`Source`."""
    try:
        snaps, atoms, _ = _collect(path)
    except (OSError, EOFError, UnicodeDecodeError) as exc:
        raise ImportRefused(f"{path}: not a readable dump file: {exc}") from exc
    position = np.stack([a["position"] for a in atoms])
    dim = _dim(position, items, path)
    flags = snaps[0].flags
    box = _fixed_box(np.stack([s.box for s in snaps]), flags, path)
    timed = all(s.time is not None for s in snaps)
    return Source(
        where=str(path), file=path, position=position[:, :, :dim], species=atoms[0]["type"],
        step=np.array([s.step for s in snaps], np.int64),
        time=np.array([s.time for s in snaps]) if timed else None, time_from="its ITEM: TIME",
        radius=atoms[0]["radius"], mass=atoms[0]["mass"], box=box[:dim],
        boundary=tuple("periodic" if flags and flags[a] == "pp" else "none" for a in range(dim)),
        parameters={"dump_columns": snaps[0].columns, "dump_box_flags": list(flags), "dump_units": snaps[0].units,
                    "dump_atom_ids": [int(atoms[0]["id"][0]), int(atoms[0]["id"][-1])]})


def files(src: Path) -> list[Path]:
    """A dump file, or the dump files of a folder (PATTERNS) sorted by name."""
    src = Path(src)
    if not src.is_dir():
        return [src]
    found = sorted({p for pattern in PATTERNS for p in src.glob(pattern) if p.is_file() and not p.name.startswith(".")})
    if not found:
        raise ImportRefused(f"{src}: no dump files ({', '.join(PATTERNS)}) in this folder")
    return found


def sources(src: Path, items: Given, limit: int | None = None) -> Iterator[tuple[str | None, Source]]:
    """(None, trajectory) for a dump file, or for each dump file of a folder (the first ``limit`` where given)."""
    for path in files(src)[:limit]:
        yield None, source(path, items)
