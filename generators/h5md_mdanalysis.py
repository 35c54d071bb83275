"""Open a graphdem H5MD file (3D) with MDAnalysis, an optional dependency (the ``dev`` extra); see docs/data.md.

MDAnalysis' H5MD reader (2.x) knows only molecular length units (Angstrom, nm, pm, fm) and refuses any other,
``m`` included, with or without ``convert_units``; its minimal topology looks for the particle group
``particles/trajectory``, ours is ``particles/all``. :func:`universe` builds a topology of N atoms from our
per-particle data and reads the trajectory with MDAnalysis' own H5MD reader, told that ``m`` is a length unit
and asked to keep it (``convert_units=False``): positions, box edges and times stay in m and s, as stored.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np

from generators.h5md import LENGTH_UNIT

if TYPE_CHECKING:
    import MDAnalysis


@cache
def si_reader() -> type:
    """MDAnalysis' H5MDReader, also accepting the SI length unit ``m`` (not converted: use convert_units=False).

    The subclass sets no ``format``, so MDAnalysis does not register it: its own "H5MD" reader is unchanged.
    """
    from MDAnalysis.coordinates.H5MD import H5MDReader

    table = H5MDReader._unit_translation

    class SIH5MDReader(H5MDReader):
        _unit_translation = {**table, "length": {**table["length"], LENGTH_UNIT: LENGTH_UNIT}}

    return SIH5MDReader


def particle_data(path: str | Path) -> dict[str, np.ndarray]:
    """Species, mass (kg) and radius (m) of every particle, for MDAnalysis' topology (types, masses, radii)."""
    with h5py.File(path, "r") as f:
        return {name: f[f"particles/all/{name}"][()] for name in ("species", "mass", "radius")}


def universe(path: str | Path) -> MDAnalysis.Universe:
    """An MDAnalysis Universe over the 3D H5MD file ``path``: atom types are our species, masses in kg, radii,
    positions and box edges in m, times in s (MDAnalysis refuses 2D files: its H5MD reader wants a 3D box)."""
    import MDAnalysis as mda

    data = particle_data(path)
    u = mda.Universe.empty(len(data["species"]), trajectory=False)
    u.add_TopologyAttr("types", data["species"].astype(str))
    u.add_TopologyAttr("masses", data["mass"].astype(np.float64))
    u.add_TopologyAttr("radii", data["radius"].astype(np.float64))
    u.load_new(str(path), format=si_reader(), convert_units=False)
    return u
