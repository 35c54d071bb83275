"""LagrangeBench HDF5 datasets (tumaer/lagrangebench, the datasets of Toshev et al., NeurIPS 2023).

Checked against tumaer/lagrangebench: ``lagrangebench/data/data.py`` (``H5Dataset``: one file per split,
``<dataset>/{train,valid,test}.h5``, beside ``metadata.json``; each trajectory a group of the file, ``"00000"``,
``"00001"``, ..., read in the order of ``f.keys()``, holding the datasets ``position`` [T, N, D] and
``particle_type`` [N]), ``lagrangebench/utils.py`` (``NodeType``: 0 fluid, 1 solid wall, 2 moving wall, 3 rigid
body; ``get_kinematic_mask``: types 1 and 2 are kinematic) and the uses of its metadata (``bounds`` [[lo, hi],
...], rows past ``dim`` unused; ``periodic_boundary_conditions`` per axis; ``dt`` the solver's step and
``write_every`` the steps between stored frames, their product the time between frames; ``dim``;
``default_connectivity_radius``; ``dx`` the particle spacing).

Frame i is step i x write_every (1 where absent) at time step x dt; the box is the bounds, periodic where the
metadata says so. Every dataset is reached inside the file and its size bounded before it is read
(generators/hdf5_guard.py).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np

from generators import h5md, hdf5_guard
from generators.importers import metadata
from generators.importers.metadata import Given, ImportRefused
from generators.importers.sims import Source

KINEMATIC_TYPES = (1, 2)        # lagrangebench/utils.py get_kinematic_mask: SOLID_WALL, MOVING_WALL
SPECIES_NAMES = {"0": "fluid", "1": "solid wall", "2": "moving wall", "3": "rigid body"}


def _boundary(meta: dict, path: Path, dim: int) -> tuple[str, ...]:
    flags = meta.get("periodic_boundary_conditions")
    if flags is None:
        return ("none",) * dim
    if not isinstance(flags, list) or len(flags) < dim or not all(isinstance(f, bool) for f in flags[:dim]):
        raise ImportRefused(f"{path}: 'periodic_boundary_conditions' must be a list of at least {dim} booleans, got "
                            f"{flags!r}")
    return tuple("periodic" if f else "none" for f in flags[:dim])


def _write_every(meta: dict, path: Path) -> int:
    every = meta.get("write_every", 1)
    if isinstance(every, bool) or not isinstance(every, int) or every < 1:
        raise ImportRefused(f"{path}: 'write_every' must be a whole number >= 1, got {every!r}")
    return every


def _dataset(f: h5py.File, key: str, path: Path, budget: hdf5_guard.Budget) -> np.ndarray:
    try:
        data = hdf5_guard.dataset(f, key, path, budget)
    except hdf5_guard.Refused as exc:
        raise ImportRefused(str(exc)) from exc
    if data is None:
        raise ImportRefused(f"{path}: missing {key}; a LagrangeBench trajectory group holds the datasets position "
                            f"[T, N, D] and particle_type [N]")
    try:
        return data[()]
    except (OSError, ValueError) as exc:
        raise ImportRefused(f"{path}: {key} is not readable (corrupt?): {exc}") from exc


def trajectories(path: Path, limit: int | None) -> Iterator[tuple[str, np.ndarray, np.ndarray]]:
    """(group, position, particle_type) for every trajectory group of one split's file, in key order."""
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise ImportRefused(f"{path}: not a readable HDF5 file (corrupt or truncated?): {exc}") from exc
    budget = hdf5_guard.Budget(path, max(h5md.MIN_DECLARED_BYTES, h5md.DECLARED_PER_FILE_BYTE * path.stat().st_size))
    with f:
        keys = sorted(f.keys())
        if not keys:
            raise ImportRefused(f"{path}: no trajectory groups; a LagrangeBench file holds groups 00000, 00001, ...")
        for key in keys[:limit]:
            yield key, _dataset(f, f"{key}/position", path, budget), _dataset(f, f"{key}/particle_type", path, budget)


def source(path: Path, key: str, position: np.ndarray, types: np.ndarray, meta: dict, meta_path: Path,
           items: Given) -> Source:
    """One trajectory group as a :class:`Source`."""
    where = f"{path}: {key}"
    if position.ndim != 3:
        raise ImportRefused(f"{where}/position must be [T, N, D], got shape {position.shape}")
    t, _, d = position.shape
    metadata.check_dim(meta, meta_path, d, items, where)
    dt, every = metadata.held_number(meta, "dt", meta_path), _write_every(meta, meta_path)
    step = np.arange(t) * every
    return Source(
        where=where, file=path, position=position, species=types, step=step,
        time=None if dt is None else step * dt,
        time_from=f"{meta_path} (dt = {dt} s per step, write_every = {every} steps per frame)",
        box=metadata.held_box(meta, meta_path, d), boundary=_boundary(meta, meta_path, d),
        kinematic_types=KINEMATIC_TYPES,
        parameters={"connectivity_radius": meta.get("default_connectivity_radius"), "species_names": SPECIES_NAMES,
                    "source_metadata": meta})


def sources(src: Path, items: Given, limit: int | None = None) -> Iterator[tuple[str | None, Source]]:
    """(split, trajectory) for every trajectory of a LagrangeBench dataset folder or split file (the first
    ``limit`` of each file where given)."""
    found, meta_path, meta = metadata.dataset_files(src, ".h5", "LagrangeBench")
    for split, path in found:
        for key, position, types in trajectories(path, limit):
            yield split, source(path, key, position, types, meta, meta_path, items)
