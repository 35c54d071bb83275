"""One simulation as an H5MD 1.1 file (see docs/data.md), validated on write and on read.

Layout::

    /h5md                          version [1, 1]; author/name; creator/name, creator/version
    /h5md/modules/units            version [1, 0], system "SI": every ``unit`` attribute is an SI unit
    /particles/all/box             dimension, boundary; edges/{value [T,D] f8, step, time}; lower [D] f8
    /particles/all/position/{value [T,N,D] f4, step [T] i8, time [T] f8}
    /particles/all/{species i4, radius f4, mass f4, kinematic bool}   [N]
    /particles/all/properties      [N, F] f4, attribute names (optional)
    /parameters                    attributes: every scene/DEM parameter and the provenance
    /observables/<name>/{value [T] f8 with its unit, step, time}        (optional)

Every ``step`` and ``time`` beside position's (box edges, observables) is a hard link to position's. Every
observable's ``value`` carries the units module's ``unit`` attribute (``Trajectory.observable_units``; one is
refused without it). Files written before the units module was declared hold ``box/edges`` as a dataset [D]; they
read as before, and so do files whose observables have no unit (none in ``observable_units``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from generators import hdf5_guard
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
    observable_units: dict[str, str] = field(default_factory=dict)     # name -> its SI unit ("J", "N", "Pa", "m")

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
        if not allow_nonfinite:
            _check_finite_positions(pos, where)
        for name in ("time", "radius", "mass", "box_lower", "box_upper"):
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


def _check_finite_positions(pos: np.ndarray, where: str) -> None:
    """Refuse the first non-finite position by frame and particle, a block of frames at a time (no mask of the
    whole array)."""
    block = max(1, 2**20 // max(1, pos[0].size))
    for start in range(0, pos.shape[0], block):
        bad = ~np.isfinite(pos[start:start + block])
        if bad.any():
            frame, particle, _ = np.unravel_index(int(np.argmax(bad)), bad.shape)
            raise H5MDError(f"{where}: non-finite position at frame {start + frame}, particle {particle}")


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
        except (json.JSONDecodeError, RecursionError):     # not JSON, or nested past the interpreter's depth
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
                _set_unit(obs.create_dataset("value", data=np.asarray(values, np.float64)),
                          _observable_unit(traj, name, path))
                _link_step_time(obs, pos)
    return path


def _observable_unit(traj: Trajectory, name: str, path: Path) -> str:
    """The unit of observable ``name``: a non-empty ASCII string (the units module's unit string, e.g. ``J``; ``1``
    for a number without dimension)."""
    unit = traj.observable_units.get(name)
    if not isinstance(unit, str) or not unit.strip() or not unit.isascii():
        raise H5MDError(f"{path}: observable {name!r} has no unit (observable_units[{name!r}] = {unit!r}); give its "
                        "SI unit as ASCII text, e.g. 'J' (the units module puts it on observables/<name>/value)")
    return unit


#: what a file may make its reader allocate (every dataset and attribute read, decompressed, plus one chunk of each
#: chunked dataset): DECLARED_PER_FILE_BYTE bytes per byte of the file (a compressed file can declare far more than
#: it holds), and MIN_DECLARED_BYTES whatever its size (a file of up to 10 MiB may make its reader allocate 256 MiB)
DECLARED_PER_FILE_BYTE, MIN_DECLARED_BYTES = 25, 256 * 2 ** 20
REQUIRED = ("particles/all/position/value", "particles/all/position/time", "particles/all/position/step",
            "particles/all/species", "particles/all/radius", "particles/all/mass", "particles/all/kinematic")
OPTIONAL = ("particles/all/box/lower", "particles/all/properties")
EDGES = "particles/all/box/edges"


def _group(f: h5py.File, key: str, path: Path, required: bool = True) -> h5py.Group | None:
    """The group at ``key``, reached inside the file (hdf5_guard.node); missing: an error when ``required``."""
    node = hdf5_guard.node(f, key, path)
    if node is None and required:
        raise H5MDError(f"{path}: not a graphdem H5MD file: missing {key}")
    if node is not None and not isinstance(node, h5py.Group):
        raise H5MDError(f"{path}: {key} must be a group, found a {type(node).__name__}")
    return node


def _dataset(f: h5py.File, key: str, path: Path, budget: hdf5_guard.Budget) -> h5py.Dataset:
    """The dataset ``key``, reached and stored inside the file, numeric, its decompressed size taken from the
    file's budget and its chunks checked before anything is read (hdf5_guard.dataset; shapes are checked by
    Trajectory.validate once read)."""
    node = hdf5_guard.dataset(f, key, path, budget)
    if node is None:
        raise H5MDError(f"{path}: not a graphdem H5MD file: missing {key}")
    return node


def _edges_key(f: h5py.File, path: Path) -> str:
    """Where the box edges are: ``edges/value`` of the time-dependent element (files with the units module), or
    ``edges`` itself, the fixed dataset [D] of older files."""
    return f"{EDGES}/value" if isinstance(hdf5_guard.node(f, EDGES, path), h5py.Group) else EDGES


def _fixed_edges(edges: np.ndarray, key: str, frames_shape: tuple[int, ...], path: Path) -> np.ndarray:
    """The box edges [D] from what ``key`` holds: a fixed dataset as it is, or a time-dependent value [T, D] whose
    rows, one per frame, must all be equal; every edge a finite positive length."""
    if key != EDGES:
        if edges.ndim != 2 or edges.shape[:1] != frames_shape or not edges.shape[0]:
            raise H5MDError(f"{path}: {key} must hold numbers of shape [T, D], one row per frame (position/time "
                            f"has shape {frames_shape}), got {edges.dtype} {edges.shape}")
        if not np.array_equal(edges, np.broadcast_to(edges[0], edges.shape), equal_nan=True):
            raise H5MDError(f"{path}: {key} changes over time; a graphdem trajectory has a fixed box")
        edges = edges[0]
    if edges.dtype.kind == "b" or not (np.all(np.isfinite(edges)) and np.all(edges > 0)):
        raise H5MDError(f"{path}: {key} must hold finite positive box edges (m), got "
                        f"{np.atleast_1d(edges).tolist()[:6]}")
    return edges


def _box(f: h5py.File, path: Path, budget: hdf5_guard.Budget, frames_shape) -> tuple[np.ndarray, np.ndarray, tuple]:
    """The box's lower and upper corners [D] and its boundary per axis."""
    box = _group(f, "particles/all/box", path)
    key = _edges_key(f, path)
    edges = _fixed_edges(_dataset(f, key, path, budget)[()], key, frames_shape, path)
    lower_set = hdf5_guard.dataset(f, "particles/all/box/lower", path, budget)
    lower = lower_set[()] if lower_set is not None else np.zeros_like(edges)
    if lower.dtype.kind == "b" or not np.all(np.isfinite(lower)):
        raise H5MDError(f"{path}: particles/all/box/lower must hold a finite corner (m), got "
                        f"{np.atleast_1d(lower).tolist()[:6]}")
    boundary = hdf5_guard.attribute(box, "boundary", "particles/all/box", path, budget, ())
    return lower, lower + edges, tuple(_text(b) for b in np.atleast_1d(boundary))


def _text(value) -> str:
    return value.decode(errors="replace") if isinstance(value, bytes) else str(value)


def _properties(f: h5py.File, path: Path, budget: hdf5_guard.Budget) -> tuple[np.ndarray | None, tuple[str, ...]]:
    """The per-particle properties [N, F] and their names, or (None, ()) when the file has none."""
    props = hdf5_guard.dataset(f, "particles/all/properties", path, budget)
    if props is None:
        return None, ()
    names = hdf5_guard.attribute(props, "names", "particles/all/properties", path, budget, ())
    return props[()], tuple(_text(n) for n in np.atleast_1d(names))


def _observables(f: h5py.File, path: Path, budget: hdf5_guard.Budget, frames_shape,
                 sel) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Every observable's value, one per frame, at the frames ``sel``, and the units of those that have one."""
    group = _group(f, "observables", path, required=False)
    observables, units = {}, {}
    for name in (group.keys() if group is not None else ()):
        key = f"observables/{name}/value"
        element = hdf5_guard.node(f, f"observables/{name}", path)
        value = hdf5_guard.dataset(f, key, path, budget) if isinstance(element, h5py.Group) else None
        if value is None or value.shape != frames_shape:
            raise H5MDError(f"{path}: {key} must be a numeric dataset of shape {frames_shape}, one value per frame")
        observables[name] = value[()][sel]
        unit = hdf5_guard.attribute(value, "unit", key, path, budget)
        if unit is not None:
            units[name] = _text(unit)
    return observables, units


def _parameters(f: h5py.File, path: Path, budget: hdf5_guard.Budget) -> dict:
    """The attributes of /parameters, JSON text decoded; {} when the file has none."""
    group = hdf5_guard.node(f, "parameters", path)
    if not isinstance(group, h5py.Group):
        return {}
    return {k: _from_attr(hdf5_guard.attribute(group, k, "parameters", path, budget)) for k in group.attrs}


def _open(path: Path) -> tuple[h5py.File, hdf5_guard.Budget]:
    """The file opened read-only and the budget of what it may make its reader allocate."""
    if not path.is_file():
        raise H5MDError(f"{path}: no such file")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise H5MDError(f"{path}: not a readable HDF5 file (corrupt or truncated?): {exc}") from exc
    return f, hdf5_guard.Budget(path, max(MIN_DECLARED_BYTES, DECLARED_PER_FILE_BYTE * path.stat().st_size))


def read(path: str | Path, frames: slice | None = None, allow_nonfinite: bool = False) -> Trajectory:
    """Read and validate an H5MD file; raise H5MDError naming the file, the field and what was expected.

    Every object is reached only through links inside the file, every dataset is checked to be stored in it and
    numeric, and its decompressed size taken from the file's budget before it is read (:mod:`generators.hdf5_guard`),
    so a small file that declares or inflates to a huge array, or points elsewhere, is refused without touching it;
    shapes are checked by Trajectory.validate, the one check for files read and written.
    """
    path = Path(path)
    f, budget = _open(path)
    sel = frames if frames is not None else slice(None)
    try:
        with f:
            version_at = _group(f, "h5md", path)
            version = tuple(int(v) for v in np.atleast_1d(hdf5_guard.attribute(version_at, "version", "h5md", path,
                                                                                budget, ())))
            if version[:1] != (1,):
                raise H5MDError(f"{path}: unsupported H5MD version {version}, expected 1.x")
            sets = {k: _dataset(f, k, path, budget) for k in REQUIRED}
            frames_shape = sets["particles/all/position/time"].shape
            lower, upper, boundary = _box(f, path, budget, frames_shape)
            props, names = _properties(f, path, budget)
            observables, observable_units = _observables(f, path, budget, frames_shape, sel)
            traj = Trajectory(
                position=sets["particles/all/position/value"][sel], time=sets["particles/all/position/time"][sel],
                step=sets["particles/all/position/step"][sel], species=sets["particles/all/species"][()],
                radius=sets["particles/all/radius"][()], mass=sets["particles/all/mass"][()],
                kinematic=sets["particles/all/kinematic"][()], box_lower=lower, box_upper=upper, boundary=boundary,
                properties=props, property_names=names, parameters=_parameters(f, path, budget),
                observables=observables, observable_units=observable_units)
    except H5MDError:
        raise
    except hdf5_guard.Refused as exc:
        raise H5MDError(str(exc)) from exc
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as exc:
        raise H5MDError(f"{path}: unreadable H5MD content (corrupt?): {exc}") from exc
    return traj.validate(str(path), allow_nonfinite)
