"""One trajectory as a source holds it (:class:`Source`), completed by the given items (generators/importers/
metadata.py) into a validated H5MD trajectory, and an import's output folder.

Where the source holds an item (a dump's radius column, a dataset's bounds or dt), the source's value is used and
a given one must agree with it (else the import is refused naming both); where it holds none, the given one is
used; where neither has it, the import is refused naming the option and the metadata key that give it.

The folder: ``<name>_<i:04d>.h5`` per trajectory (numbered across the splits in the source's order),
``splits.csv`` (id, split, path, source: the table `graphdem dataset --table` takes) where the source has splits,
and ``import.json`` (the format, the source, each file's SHA-256 and the items used), written whole and
atomically.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from generators import h5md
from generators.atomic import atomic_path
from generators.importers.metadata import Given, ImportRefused, how_to_give, per_particle, sha256, volume

MARKER = "import.json"          # the file every import folder holds (an earlier import may be replaced)
RTOL = 1e-6                     # a given value agrees with the source's within this relative tolerance


@dataclass
class Source:
    """One trajectory of a source file; None (or empty) where the format holds nothing of an item."""

    where: str                              # the file and the entry in it, for messages
    file: Path                              # the file it was read from (its SHA-256 is the provenance)
    position: np.ndarray                    # [T, N, D]
    species: np.ndarray                     # [N] particle types
    step: np.ndarray                        # [T] engine steps (frame numbers where the format has none)
    time: np.ndarray | None = None          # [T] s, where the source holds the time step
    time_from: str = ""                     # how the source gives the times, in words
    radius: np.ndarray | None = None        # [N] m
    mass: np.ndarray | None = None          # [N] kg
    box: np.ndarray | None = None           # [D, 2] m
    boundary: tuple[str, ...] = ()          # per axis "none" | "periodic"
    kinematic_types: tuple[int, ...] = ()   # the format's convention, replaced by a given kinematic_types
    properties: np.ndarray | None = None    # [N, F]
    property_names: tuple[str, ...] = ()
    parameters: dict = field(default_factory=dict)   # the format's own metadata


def _shape(value) -> str:
    return f"{type(value).__name__} {getattr(value, 'dtype', '')} {np.shape(value)}".replace("  ", " ")


def _positions(src: Source) -> np.ndarray:
    pos = src.position
    if not isinstance(pos, np.ndarray) or pos.dtype.kind not in "fiu" or pos.ndim != 3 or pos.shape[2] not in (2, 3) \
            or pos.shape[0] < 2 or pos.shape[1] < 1:
        raise ImportRefused(f"{src.where}: positions must be numbers of shape [T, N, D] with at least 2 frames, 1 "
                            f"particle and D 2 or 3, got {_shape(pos)}")
    return pos


def _species(src: Source, n: int) -> np.ndarray:
    kinds = np.asarray(src.species)
    if kinds.dtype.kind not in "fiu" or kinds.shape != (n,) or not np.all(np.isfinite(kinds)) \
            or not np.array_equal(kinds, np.round(kinds)) or kinds.min() < 0:
        raise ImportRefused(f"{src.where}: particle types must be {n} whole numbers >= 0, one per particle, got "
                            f"{_shape(kinds)}")
    return kinds.astype(np.int32)


def _held(value, n: int, key: str, src: Source) -> np.ndarray | None:
    """A per-particle array the source holds, checked: [N] finite numbers."""
    if value is None:
        return None
    value = np.asarray(value)
    if value.dtype.kind not in "fiu" or value.shape != (n,) or not np.all(np.isfinite(value)):
        raise ImportRefused(f"{src.where}: the source's {key} must be {n} finite numbers, one per particle, got "
                            f"{_shape(value)}")
    return value.astype(np.float64)


def _agree(key: str, held, from_items, origin: str, src: Source, held_from: str = "the source"):
    """The source's value of an item, else the given one; both: they must agree (module docstring)."""
    if from_items is None:
        return held
    if held is None:
        return from_items
    if np.shape(held) != np.shape(from_items) or not np.allclose(held, from_items, rtol=RTOL, atol=0):
        first = np.argmax(~np.isclose(held, from_items, rtol=RTOL, atol=0)) if np.shape(held) == np.shape(
            from_items) else None
        detail = (f"shape {np.shape(held)} against {np.shape(from_items)}" if first is None else
                  f"{np.ravel(held)[first]:.6g} against {np.ravel(from_items)[first]:.6g} at entry {first}")
        raise ImportRefused(f"{src.where}: {held_from} gives the {key} and {origin} another ({detail}); drop "
                            f"{origin} or make it agree")
    return held


def _mass(src: Source, items: Given, species, radius, kinematic, dim: int) -> np.ndarray:
    """The mass per particle: the source's, else the given mass, else the given density times the volume."""
    held = _held(src.mass, len(species), "mass", src)
    from_items, origin = None, ""
    for key in ("mass", "density"):
        if key in items:
            origin = items.where(key)
            from_items = per_particle(key, items.get(key), species, origin, kinematic)
            if key == "density":
                from_items = from_items * volume(radius, dim)
            break
    if held is None and from_items is None:
        raise ImportRefused(f"{src.where}: no particle mass (the source holds none): give --mass (kg) or --density "
                            f"(kg/m^3), a number or TYPE=VALUE per type, or the key 'mass' or 'density' of a "
                            f"metadata file (--meta FILE)")
    return _agree("mass", held, from_items, origin, src)


def _given_time(step: np.ndarray, items: Given, where: str) -> np.ndarray | None:
    """The frame times the given dt (s per step) or frame_interval (s per frame, frames evenly spaced) make."""
    dt, interval = items.get("dt"), items.get("frame_interval")
    if interval is not None:
        gaps = np.unique(np.diff(step))
        if len(gaps) != 1 or gaps[0] <= 0:
            raise ImportRefused(f"{where}: the frames are {gaps.min()} to {gaps.max()} steps apart, so "
                                f"{items.where('frame_interval')} does not give their times: give dt (s per step)")
        per_step = interval / float(gaps[0])
        if dt is not None and not math.isclose(per_step, dt, rel_tol=RTOL):
            raise ImportRefused(f"{where}: {items.where('dt')} ({dt} s per step) and {items.where('frame_interval')} "
                                f"({interval} s per {gaps[0]} steps) disagree; give one")
        dt = per_step
    return None if dt is None else np.asarray(step, np.float64) * dt


def _times(src: Source, items: Given) -> np.ndarray:
    from_items = _given_time(src.step, items, src.where)
    if src.time is None and from_items is None:
        raise ImportRefused(f"{src.where}: no frame times (the source holds no time step): give --dt (s per step) or "
                            f"--frame-interval (s between frames), or the key 'dt' or 'frame_interval' of a metadata "
                            f"file (--meta FILE)")
    origin = items.where("dt" if "dt" in items else "frame_interval")
    return _agree("frame times", src.time, from_items, origin, src, src.time_from or "the source")


def _missing(key: str, src: Source, what: str) -> ImportRefused:
    return ImportRefused(f"{src.where}: no {what} (the source holds none): {how_to_give(key)}")


def trajectory(src: Source, items: Given, provenance: dict) -> h5md.Trajectory:
    """``src`` completed by ``items`` into a validated trajectory whose parameters carry ``provenance``."""
    pos = _positions(src)
    t, n, d = pos.shape
    if items.get("dim") not in (None, d):
        raise ImportRefused(f"{src.where}: positions have {d} coordinates per particle, but {items.where('dim')} "
                            f"says dim {items.get('dim')}")
    species = _species(src, n)
    kinds = tuple(items.get("kinematic_types")) if "kinematic_types" in items else tuple(src.kinematic_types)
    kinematic = np.isin(species, kinds)
    given_radius = per_particle("radius", items.get("radius"), species, items.where("radius")) \
        if "radius" in items else None
    radius = _agree("radius", _held(src.radius, n, "radius", src), given_radius, items.where("radius"), src)
    if radius is None:
        raise _missing("radius", src, "particle radius (m)")
    mass = _mass(src, items, species, radius, kinematic, d)
    box = _agree("box", src.box, None if "box" not in items else np.asarray(items.get("box")),
                 items.where("box"), src)
    if box is None:
        raise _missing("box", src, "domain box")
    time = _times(src, items)
    parameters = {**src.parameters, **provenance, "kinematic_types": list(kinds),
                  "frame_interval": float(np.median(np.diff(time)))}
    traj = h5md.Trajectory(
        position=pos, time=time, step=np.asarray(src.step, np.int64), species=species, radius=radius, mass=mass,
        kinematic=kinematic, box_lower=np.asarray(box)[:, 0], box_upper=np.asarray(box)[:, 1],
        boundary=tuple(src.boundary) or ("none",) * d, properties=src.properties,
        property_names=tuple(src.property_names), parameters=parameters)
    return traj.validate(src.where)


def write(out_dir: Path, sources: Iterable[tuple[str | None, Source]], items: Given, record: dict) -> list[dict]:
    """Write every trajectory of ``sources`` ((split or None, source) pairs) into the folder ``out_dir``, replaced
    whole and atomically (module docstring); ``record`` (format, source, name, options) is the provenance every
    sim and import.json carry. Returns the rows of the split table."""
    out_dir, name = Path(out_dir), record["name"]
    rows: list[dict] = []
    digests: dict[Path, str] = {}
    with atomic_path(out_dir) as tmp:
        tmp.mkdir()
        for i, (split, src) in enumerate(sources):
            if src.file not in digests:
                digests[src.file] = sha256(src.file)
            sim_id = f"{name}_{i:04d}"
            provenance = {"scene": name, "dataset": name, "source_format": record["format"],
                          "source_file": str(src.file.resolve()), "source_sha256": digests[src.file],
                          "source_entry": src.where, "importer_options": record}
            h5md.write(tmp / f"{sim_id}.h5", trajectory(src, items, provenance))
            rows.append({"id": sim_id, "split": split, "path": str(out_dir / f"{sim_id}.h5"), "source": src.where})
        if not rows:
            raise ImportRefused(f"{record['source']}: no trajectories in it")
        if all(row["split"] is not None for row in rows):
            _write_table(tmp / "splits.csv", rows)
        (tmp / MARKER).write_text(json.dumps({**record, "sims": len(rows),
                                              "files": {str(p.resolve()): d for p, d in digests.items()}}, indent=2))
    return rows


def _write_table(path: Path, rows: list[dict]) -> None:
    import pandas as pd
    pd.DataFrame(rows, columns=["id", "split", "path", "source"]).to_csv(path, index=False)
