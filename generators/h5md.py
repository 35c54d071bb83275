"""One simulation as an H5MD 1.1 file (see docs/data.md), validated on write and on read.

Layout::

    /h5md                          version [1, 1]; author/name; creator/name, creator/version
    /h5md/modules/units            version [1, 0], system "SI": every ``unit`` attribute is an SI unit
    /particles/all/box             dimension, boundary; edges/{value [T,D] f8, step, time}; lower [D] f8
    /particles/all/position/{value [T,N,D] f4, step [T] i8, time [T] f8}
    /particles/all/{species i4, radius f4, mass f4, kinematic bool}   [N]
    /particles/all/properties      [N, F] f4, attribute names (optional)
    /parameters                    attributes: every scene/DEM parameter and the provenance
    /observables/<name>/{value, step, time}                           (optional)

Every ``step`` and ``time`` beside position's (box edges, observables) is a hard link to position's. Files
written before the units module was declared hold ``box/edges`` as a dataset [D]; they read as before.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from generators.atomic import atomic_path, h5_file

H5MD_VERSION = (1, 1)
UNITS_MODULE_VERSION = (1, 0)
UNIT_SYSTEM = "SI"
LENGTH_UNIT, TIME_UNIT, MASS_UNIT = "m", "s", "kg"
CREATOR = "graphdem"
CREATOR_VERSION = "0.1.0"


class H5MDError(ValueError):
    """An H5MD file (or a trajectory about to be written) is malformed; the message names it."""


@dataclass
class Trajectory:
    """Positions of N particles in D dimensions over T frames, plus per-particle data."""

    position: np.ndarray            # [T, N, D]
    time: np.ndarray                # [T] s
    step: np.ndarray                # [T] engine iteration
    species: np.ndarray             # [N] int
    radius: np.ndarray              # [N] m
    mass: np.ndarray                # [N] kg
    kinematic: np.ndarray           # [N] bool, True: position prescribed, never predicted
    box_lower: np.ndarray           # [D] m
    box_upper: np.ndarray           # [D] m
    boundary: tuple[str, ...] = ()  # per axis "none" | "periodic"
    properties: np.ndarray | None = None      # [N, F]
    property_names: tuple[str, ...] = ()
    parameters: dict = field(default_factory=dict)
    observables: dict[str, np.ndarray] = field(default_factory=dict)   # name -> [T]

    @property
    def dim(self) -> int:
        return int(self.position.shape[-1])

    @property
    def n_frames(self) -> int:
        return int(self.position.shape[0])

    @property
    def n_particles(self) -> int:
        return int(self.position.shape[1])

    def validate(self, where: str = "trajectory", allow_nonfinite: bool = False) -> Trajectory:
        """Check shapes, finiteness, increasing times and the kinematic mask; raise H5MDError.

        ``allow_nonfinite`` admits NaN positions (a surrogate rollout that blew up is stored as
        such, never hidden); every other check still applies.
        """
        pos = np.asarray(self.position)
        if pos.ndim != 3 or pos.shape[2] not in (2, 3):
            raise H5MDError(f"{where}: position must be [T, N, D] with D in (2, 3), got shape {pos.shape}")
        t, n, d = pos.shape
        if t < 1 or n < 1:
            raise H5MDError(f"{where}: position has no frames or no particles (shape {pos.shape})")
        if pos.shape[0] < 2:
            raise H5MDError(f"{where}: position has one frame (shape {pos.shape}); a trajectory needs at least 2")
        for name in ("position", "time", "radius", "mass", "box_lower", "box_upper", "properties", "step", "species"):
            kinds = "iu" if name in ("step", "species") else "fiu"
            value = getattr(self, name)
            if value is not None and np.asarray(value).dtype.kind not in kinds:
                raise H5MDError(f"{where}: {name} must hold {'integers' if kinds == 'iu' else 'numbers'}, got dtype "
                                f"{np.asarray(value).dtype}")
        species = np.asarray(self.species)
        if species.size and species.min() < 0:
            raise H5MDError(f"{where}: species must be non-negative, found {species.min()}")
        for name, arr, shape in (
            ("time", self.time, (t,)), ("step", self.step, (t,)),
            ("species", self.species, (n,)), ("radius", self.radius, (n,)),
            ("mass", self.mass, (n,)), ("kinematic", self.kinematic, (n,)),
            ("box_lower", self.box_lower, (d,)), ("box_upper", self.box_upper, (d,)),
        ):
            if arr is None:
                raise H5MDError(f"{where}: {name} is missing")
            if np.shape(arr) != shape:
                raise H5MDError(f"{where}: {name} has shape {np.shape(arr)}, expected {shape}")
        bad = ~np.isfinite(pos)
        if bad.any() and not allow_nonfinite:
            frame, particle, _ = np.argwhere(bad)[0]
            raise H5MDError(f"{where}: non-finite position at frame {frame}, particle {particle}")
        for name in ("time", "radius", "mass"):
            if not np.all(np.isfinite(getattr(self, name))):
                raise H5MDError(f"{where}: non-finite values in {name}")
        if t > 1 and not np.all(np.diff(np.asarray(self.time)) > 0):
            raise H5MDError(f"{where}: frame times are not strictly increasing")
        if np.asarray(self.kinematic).dtype != bool:
            raise H5MDError(f"{where}: kinematic mask must be boolean, got {np.asarray(self.kinematic).dtype}")
        moving = ~np.asarray(self.kinematic, bool)
        if np.any(np.asarray(self.radius) <= 0) or np.any(np.asarray(self.mass)[moving] <= 0):
            raise H5MDError(f"{where}: radius, and the mass of moving particles, must be positive")
        if np.any(np.asarray(self.mass) < 0):
            raise H5MDError(f"{where}: mass must not be negative (0 marks a kinematic particle of infinite mass)")
        if not np.all(np.asarray(self.box_upper) > np.asarray(self.box_lower)):
            raise H5MDError(f"{where}: box upper corner must exceed lower corner")
        if self.boundary and len(self.boundary) != d:
            raise H5MDError(f"{where}: boundary has {len(self.boundary)} entries for {d} axes")
        if self.properties is not None:
            props = np.asarray(self.properties)
            if props.ndim != 2 or props.shape[0] != n or props.shape[1] != len(self.property_names):
                raise H5MDError(f"{where}: properties must be [N, F] with F = len(property_names)")
            if not np.all(np.isfinite(props)):
                raise H5MDError(f"{where}: non-finite per-particle properties")
        for name, values in self.observables.items():
            if np.shape(values) != (t,):
                raise H5MDError(f"{where}: observable {name!r} must have one value per frame")
        return self


def _attr_value(value):
    if isinstance(value, (bool, int, float, str, np.integer, np.floating)):
        return value
    if value is None:
        return "null"
    return json.dumps(value)


def _from_attr(value):
    if isinstance(value, bytes):
        value = value.decode()
    if isinstance(value, str) and (value[:1] in "[{" or value == "null"):
        try:
            return json.loads(value)
        except json.JSONDecodeError:
            return value
    if isinstance(value, np.generic):
        return value.item()
    return value


def _set_unit(node: h5py.Dataset, unit: str) -> None:
    """Attach the units module's ``unit`` attribute: scalar, variable-length ASCII string (MDAnalysis reads
    only variable-length unit strings)."""
    node.attrs.create("unit", unit, dtype=h5py.string_dtype("ascii"))


def _write_h5md_group(f: h5py.File, author: str) -> None:
    """The /h5md metadata: spec version, author, creator and the declared units module."""
    h5md = f.create_group("h5md")
    h5md.attrs["version"] = np.array(H5MD_VERSION, dtype=np.int32)
    f.create_group("h5md/author").attrs["name"] = author
    creator = f.create_group("h5md/creator")
    creator.attrs["name"] = CREATOR
    creator.attrs["version"] = CREATOR_VERSION
    units = f.create_group("h5md/modules/units")
    units.attrs["version"] = np.array(UNITS_MODULE_VERSION, dtype=np.int32)
    units.attrs.create("system", UNIT_SYSTEM, dtype=h5py.string_dtype("ascii"))


def _write_position(part: h5py.Group, traj: Trajectory) -> h5py.Group:
    """The time-dependent position element: value [T, N, D] (m), step [T], time [T] (s)."""
    _, n, d = traj.position.shape
    pos = part.create_group("position")
    pos.create_dataset("value", data=np.asarray(traj.position, np.float32),
                       chunks=(1, n, d), compression="gzip", compression_opts=4, shuffle=True)
    pos.create_dataset("step", data=np.asarray(traj.step, np.int64))
    pos.create_dataset("time", data=np.asarray(traj.time, np.float64))
    _set_unit(pos["time"], TIME_UNIT)
    _set_unit(pos["value"], LENGTH_UNIT)
    return pos


def _link_step_time(element: h5py.Group, pos: h5py.Group) -> None:
    """Make ``element``'s step and time hard links to position's (H5MD: elements sampled at equal times)."""
    element["step"] = pos["step"]
    element["time"] = pos["time"]


def _write_box(part: h5py.Group, traj: Trajectory, pos: h5py.Group) -> None:
    """The box: dimension, boundary, edges as a time-dependent element (the fixed edges once per frame, step and
    time linked to position's, as H5MD asks of a particle group's box) and our lower corner [D]."""
    t, _, d = traj.position.shape
    lower = np.asarray(traj.box_lower, np.float64)
    edges = np.asarray(traj.box_upper, np.float64) - lower
    box = part.create_group("box")
    box.attrs["dimension"] = np.int32(d)
    box.attrs["boundary"] = np.array(traj.boundary or ("none",) * d, dtype="S8")
    element = box.create_group("edges")
    _link_step_time(element, pos)
    _set_unit(element.create_dataset("value", data=np.broadcast_to(edges, (t, d))), LENGTH_UNIT)
    _set_unit(box.create_dataset("lower", data=lower), LENGTH_UNIT)


def write(path: str | Path, traj: Trajectory, author: str = "graphdem", allow_nonfinite: bool = False) -> Path:
    """Validate ``traj`` and write it atomically to ``path`` as H5MD."""
    path = Path(path)
    traj.validate(str(path), allow_nonfinite)
    with atomic_path(path) as tmp:
        with h5_file(tmp) as f:        # built in memory: HDF5 never writes to the disk itself
            _write_h5md_group(f, author)
            part = f.create_group("particles/all")
            pos = _write_position(part, traj)
            _write_box(part, traj, pos)
            part.create_dataset("species", data=np.asarray(traj.species, np.int32))
            _set_unit(part.create_dataset("radius", data=np.asarray(traj.radius, np.float32)), LENGTH_UNIT)
            _set_unit(part.create_dataset("mass", data=np.asarray(traj.mass, np.float32)), MASS_UNIT)
            part.create_dataset("kinematic", data=np.asarray(traj.kinematic, bool))
            if traj.properties is not None:
                props = part.create_dataset("properties", data=np.asarray(traj.properties, np.float32))
                props.attrs["names"] = np.array(traj.property_names, dtype="S64")
            params = f.create_group("parameters")
            for key, value in traj.parameters.items():
                params.attrs[key] = _attr_value(value)
            for name, values in traj.observables.items():
                obs = f.create_group(f"observables/{name}")
                obs.create_dataset("value", data=np.asarray(values, np.float64))
                _link_step_time(obs, pos)
    return path


def _need(f: h5py.File, key: str, path: Path):
    if key not in f:
        raise H5MDError(f"{path}: not a graphdem H5MD file: missing {key}")
    return f[key]


#: the most an array may declare, uncompressed, per byte of the file (a compressed file can declare far more
#: than it holds); every file may declare MIN_DECLARED_BYTES
DECLARED_PER_FILE_BYTE, MIN_DECLARED_BYTES = 200, 256 * 2 ** 20
REQUIRED = ("particles/all/position/value", "particles/all/position/time", "particles/all/position/step",
            "particles/all/species", "particles/all/radius", "particles/all/mass", "particles/all/kinematic")
OPTIONAL = ("particles/all/box/lower", "particles/all/properties")
EDGES = "particles/all/box/edges"


def _dataset(f: h5py.File, key: str, path: Path, limit: int) -> h5py.Dataset:
    """The dataset ``key``, checked to be one and to declare at most ``limit`` bytes before anything is read
    (dtypes and shapes are checked by Trajectory.validate once read)."""
    node = _need(f, key, path)
    if not isinstance(node, h5py.Dataset):
        raise H5MDError(f"{path}: {key} must be a dataset, found a {type(node).__name__}")
    declared = int(np.prod(node.shape, dtype=np.float64)) * node.dtype.itemsize
    if declared > limit:
        raise H5MDError(f"{path}: {key} declares shape {node.shape} ({declared / 2**20:,.0f} MiB), more than "
                        f"{limit / 2**20:,.0f} MiB for a file of {path.stat().st_size / 2**20:,.2f} MiB; refused "
                        f"before reading")
    return node


def _edges_key(f: h5py.File) -> str:
    """Where the box edges are: ``edges/value`` of the time-dependent element (files with the units module), or
    ``edges`` itself, the fixed dataset [D] of older files."""
    return f"{EDGES}/value" if isinstance(f.get(EDGES), h5py.Group) else EDGES


def _fixed_edges(edges: np.ndarray, key: str, frames_shape: tuple[int, ...], path: Path) -> np.ndarray:
    """The box edges [D] from what ``key`` holds: a fixed dataset as it is (its shape is checked by
    Trajectory.validate), or a time-dependent value [T, D] whose rows, one per frame, must all be equal."""
    if key == EDGES:
        return edges
    if edges.dtype.kind not in "fiu" or edges.ndim != 2 or edges.shape[:1] != frames_shape or not edges.shape[0]:
        raise H5MDError(f"{path}: {key} must hold numbers of shape [T, D], one row per frame (position/time has "
                        f"shape {frames_shape}), got {edges.dtype} {edges.shape}")
    if not np.array_equal(edges, np.broadcast_to(edges[0], edges.shape), equal_nan=True):
        raise H5MDError(f"{path}: {key} changes over time; a graphdem trajectory has a fixed box")
    return edges[0]


def read(path: str | Path, frames: slice | None = None, allow_nonfinite: bool = False) -> Trajectory:
    """Read and validate an H5MD file; raise H5MDError naming the file, the field and what was expected.

    Every dataset is checked to be one and its declared size bounded before it is read, so a small file that
    declares a huge array is refused without allocating it; dtypes and shapes are checked by
    Trajectory.validate, the one check for files read and written.
    """
    path = Path(path)
    if not path.is_file():
        raise H5MDError(f"{path}: no such file")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise H5MDError(f"{path}: not a readable HDF5 file (corrupt or truncated?): {exc}") from exc
    limit = max(MIN_DECLARED_BYTES, DECLARED_PER_FILE_BYTE * path.stat().st_size)
    try:
        with f:
            version = tuple(int(v) for v in np.atleast_1d(_need(f, "h5md", path).attrs.get("version", ())))
            if version[:1] != (1,):
                raise H5MDError(f"{path}: unsupported H5MD version {version}, expected 1.x")
            sel = frames if frames is not None else slice(None)
            box = _need(f, "particles/all/box", path)
            if not isinstance(box, h5py.Group):
                raise H5MDError(f"{path}: particles/all/box must be a group")
            edges_key = _edges_key(f)
            sets = {k: _dataset(f, k, path, limit) for k in (*REQUIRED, edges_key, *(k for k in OPTIONAL if k in f))}
            frames_shape = sets["particles/all/position/time"].shape
            edges = _fixed_edges(sets[edges_key][()], edges_key, frames_shape, path)
            lower = sets["particles/all/box/lower"][()] if "particles/all/box/lower" in sets else np.zeros_like(edges)
            props = names = None
            if "particles/all/properties" in sets:
                props = sets["particles/all/properties"][()]
                names = tuple(n.decode() if isinstance(n, bytes) else str(n)
                              for n in np.atleast_1d(sets["particles/all/properties"].attrs.get("names", ())))
            observables = {}
            if "observables" in f:
                for name, grp in f["observables"].items():
                    value = grp.get("value") if isinstance(grp, h5py.Group) else None
                    numeric = isinstance(value, h5py.Dataset) and value.dtype.kind in "fiu"
                    if not numeric or value.shape != frames_shape:
                        raise H5MDError(f"{path}: observables/{name}/value must be a numeric dataset of shape "
                                        f"{frames_shape}, one value per frame")
                    observables[name] = value[()][sel]
            traj = Trajectory(
                position=sets["particles/all/position/value"][sel],
                time=sets["particles/all/position/time"][sel],
                step=sets["particles/all/position/step"][sel],
                species=sets["particles/all/species"][()],
                radius=sets["particles/all/radius"][()],
                mass=sets["particles/all/mass"][()],
                kinematic=sets["particles/all/kinematic"][()],
                box_lower=lower, box_upper=lower + edges,
                boundary=tuple(b.decode() if isinstance(b, bytes) else str(b)
                               for b in np.atleast_1d(box.attrs.get("boundary", ()))),
                properties=props, property_names=names or (),
                parameters={k: _from_attr(v) for k, v in f["parameters"].attrs.items()}
                if isinstance(f.get("parameters"), h5py.Group) else {},
                observables=observables,
            )
    except H5MDError:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as exc:
        raise H5MDError(f"{path}: unreadable H5MD content (corrupt?): {exc}") from exc
    return traj.validate(str(path), allow_nonfinite)
