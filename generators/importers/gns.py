"""GNS ``.npz`` trajectories: geoelements/gns and DeepMind's learning_to_simulate datasets as GNS stores them.

Checked against geoelements/gns: ``gns/data_loader.py`` (``load_npz_data``: ``np.load(path, allow_pickle=True)``;
the entry ``gns_data`` when present, an object array of trajectories, else every entry of the file is one; each a
tuple ``(positions [T, N, D], particle_type[, material_property])``, particle_type an array [N] or one number)
and ``gns/reading_utils.py`` (``read_metadata``: ``metadata.json`` beside the data, newer files split by purpose
``{"train": {...}, "rollout": {...}}``; keys bounds, dt, dim, default_connectivity_radius, sequence_length,
vel_mean/std, acc_mean/std). Its converters write ``np.savez_compressed(path, simulation_trajectory_0=(positions,
particle_type), ...)`` (an object array of 2 per entry) or ``gns_data=`` an object array of such tuples; its
train.py treats particle type 3 (``KINEMATIC_PARTICLE_ID``) as kinematic. A dataset folder holds ``train.npz``,
``valid.npz``, ``test.npz`` and ``metadata.json``.

Also read: a dict per trajectory (``positions``/``position``, ``particle_type``, ``material_property``) and a file
whose entries are ``positions``/``position`` and ``particle_type`` themselves (one trajectory, no pickle).

Entries are read with ``allow_pickle=False``; an object array (which only a pickle holds) is read with an unpickler
that admits numpy arrays and numpy scalars and nothing else (generators/solidgn/safe_pickle.py), so a file that
names any other callable is refused by name before it runs.

Frame i is step i at time i x the metadata's ``dt``; the box is its ``bounds``; the material property, where
present, becomes the per-particle property ``material_property``.
"""

from __future__ import annotations

import io
import pickle
import zipfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from generators.importers.metadata import (
    Given,
    ImportRefused,
    check_dim,
    dataset_files,
    held_box,
    held_number,
)
from generators.importers.sims import Source
from generators.solidgn import safe_pickle

KINEMATIC_TYPES = (3,)          # gns/train.py, learning_to_simulate/train.py: KINEMATIC_PARTICLE_ID = 3
POSITIONS, TYPES, MATERIAL = ("positions", "position"), ("particle_type", "particle_types"), "material_property"
NUMPY_SCALARS = {("numpy.core.multiarray", "scalar"), ("numpy._core.multiarray", "scalar")}


class _Unpickler(safe_pickle.NumpyOnlyUnpickler):
    """The numpy-only unpickler, admitting numpy scalars as well (a particle type or material property stored as
    ``np.int64``/``np.float64``)."""

    def find_class(self, module: str, name: str):
        if (module, name) in NUMPY_SCALARS:
            return pickle.Unpickler.find_class(self, module, name)
        return super().find_class(module, name)


def _object_entry(npz: np.lib.npyio.NpzFile, member: str, where: str) -> np.ndarray:
    """An object array entry, unpickled with :class:`_Unpickler` after its .npy header."""
    with npz.zip.open(member) as fp:
        try:
            version = np.lib.format.read_magic(fp)
            header = {(1, 0): np.lib.format.read_array_header_1_0,
                      (2, 0): np.lib.format.read_array_header_2_0}[version](fp)
        except (ValueError, KeyError) as exc:
            raise ImportRefused(f"{where}: not a readable .npy entry: {exc}") from exc
        payload = fp.read()
    try:
        value = _Unpickler(io.BytesIO(payload), where).load()
    except safe_pickle.UnsafePickle:
        raise
    except Exception as exc:   # noqa: BLE001 - a corrupt pickle raises many kinds of errors
        raise ImportRefused(f"{where}: not a readable pickled array (corrupt or truncated?): {exc}") from exc
    if not isinstance(value, np.ndarray) or value.shape != header[0]:
        raise ImportRefused(f"{where}: the pickle holds {type(value).__name__}, not the array of shape {header[0]} "
                            f"its header declares")
    return value


def _entry(npz: np.lib.npyio.NpzFile, key: str, path: Path) -> np.ndarray:
    where = f"{path}: {key}"
    try:
        return npz[key]
    except ValueError as exc:
        if "allow_pickle" not in str(exc):
            raise ImportRefused(f"{where}: not a readable array: {exc}") from exc
    except (OSError, EOFError, zipfile.BadZipFile) as exc:
        raise ImportRefused(f"{where}: not a readable array (corrupt or truncated?): {exc}") from exc
    return _object_entry(npz, f"{key}.npy", where)


def entries(path: Path) -> Iterator[tuple[str, object]]:
    """(where, trajectory) for every trajectory of a GNS .npz, in the file's order."""
    try:
        npz = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise ImportRefused(f"{path}: not a readable .npz file (corrupt or truncated?): {exc}") from exc
    if not isinstance(npz, np.lib.npyio.NpzFile):
        raise ImportRefused(f"{path}: a single array, not an .npz of trajectories")
    with npz:
        keys = list(npz.files)
        if not keys:
            raise ImportRefused(f"{path}: no entries; a GNS .npz holds one entry per trajectory")
        if any(k in keys for k in POSITIONS) and any(k in keys for k in TYPES):
            yield f"{path}", {k: _entry(npz, k, path) for k in keys}
            return
        for key in keys:
            value = _entry(npz, key, path)
            if key == "gns_data":
                for i, item in enumerate(value):
                    yield f"{path}: gns_data[{i}]", item
            else:
                yield f"{path}: {key}", value


def _first(data: dict, names) -> object:
    return next((data[n] for n in names if n in data), None)


def parts(item, where: str) -> tuple[object, object, object]:
    """(positions, particle_type, material_property or None) of one trajectory as GNS stores it."""
    if isinstance(item, np.ndarray) and item.dtype == object and item.ndim == 0:
        item = item.item()
    if isinstance(item, dict):
        return _first(item, POSITIONS), _first(item, TYPES), item.get(MATERIAL)
    if isinstance(item, tuple | list) or (isinstance(item, np.ndarray) and item.dtype == object and item.ndim == 1):
        if len(item) in (2, 3):
            return item[0], item[1], item[2] if len(item) == 3 else None
    raise ImportRefused(f"{where}: a GNS trajectory is (positions [T, N, D], particle_type [N][, "
                        f"material_property]) or a dict of those, got {type(item).__name__} "
                        f"{getattr(item, 'dtype', '')} of shape {np.shape(item) if not isinstance(item, dict) else ''}")


def _per_particle(value, n: int, name: str, where: str) -> np.ndarray:
    """An array [N], or one number for every particle."""
    value = np.asarray(value)
    if value.ndim == 0 and value.dtype.kind in "fiu":
        return np.full(n, value[()])
    if value.shape != (n,):
        raise ImportRefused(f"{where}: {name} must be one number or {n} (one per particle), got shape {value.shape}")
    return value


def source(path: Path, where: str, item, meta: dict, meta_path: Path, items: Given) -> Source:
    """One trajectory as a :class:`Source`: times from the metadata's dt, box from its bounds."""
    positions, types, material = parts(item, where)
    if not isinstance(positions, np.ndarray) or positions.ndim != 3:
        raise ImportRefused(f"{where}: positions must be an array [T, N, D], got {type(positions).__name__} of "
                            f"shape {np.shape(positions)}")
    t, n, d = positions.shape
    check_dim(meta, meta_path, d, items, where)
    dt = held_number(meta, "dt", meta_path)
    properties = None if material is None else _per_particle(material, n, MATERIAL, where).astype(float)[:, None]
    return Source(
        where=where, file=path, position=positions, species=_per_particle(types, n, "particle_type", where),
        step=np.arange(t), time=None if dt is None else np.arange(t) * dt,
        time_from=f"{meta_path} (dt = {dt} s per frame)", box=held_box(meta, meta_path, d),
        kinematic_types=KINEMATIC_TYPES, properties=properties,
        property_names=(MATERIAL,) if material is not None else (),
        parameters={"connectivity_radius": meta.get("default_connectivity_radius"), "source_metadata": meta})


def sources(src: Path, items: Given, limit: int | None = None) -> Iterator[tuple[str | None, Source]]:
    """(split, trajectory) for every trajectory of a GNS dataset folder or .npz file (the first ``limit`` of each
    file where given)."""
    found, meta_path, meta = dataset_files(src, ".npz", "GNS")
    for split, path in found:
        for i, (where, item) in enumerate(entries(path)):
            if limit is not None and i >= limit:
                break
            yield split, source(path, where, item, meta, meta_path, items)
