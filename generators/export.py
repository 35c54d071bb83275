"""H5MD trajectories as ParaView time series: one .vtu per exported frame, listed with its time in a .pvd.

A series ``NAME.pvd`` lists the frames ``NAME/frame_<t>.vtu`` (t: the recorded frame index, six digits or
more), each an unstructured grid of N points and N vertex cells with the point data of :func:`point_data`
(names and units in docs/export.md). 2D trajectories get z = 0. The .vtu files are written by meshio; the
.pvd, a format meshio does not write, by xml.etree.

Writing is atomic per series: the frames are written into a temporary folder, the old ``NAME.pvd`` (if any)
is removed before that folder replaces ``NAME/``, and the new ``NAME.pvd`` is renamed into place last. So a
series exists exactly when its .pvd does, and a failed or killed export never leaves a .pvd that lists
missing or half-written frames.
"""

from __future__ import annotations

import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import meshio
import numpy as np

from generators import h5md
from generators.atomic import atomic_outputs

#: the point data every frame carries (a truth adds ERROR_FIELDS); per-particle properties keep their own names
#: unless they clash with one of these, when they are written as ``property_<name>``
BASE_FIELDS = ("id", "type", "radius", "mass", "kinematic", "velocity")
ERROR_FIELDS = ("error", "error_radii")


class ExportError(ValueError):
    """A trajectory cannot be exported as asked (a truth of other particles or frames, a bad --every)."""


@dataclass(frozen=True)
class Series:
    """What :func:`export` wrote: the .pvd, its frames folder, the recorded frames exported and their times."""

    pvd: Path
    frames_dir: Path
    frames: tuple[int, ...]
    times: tuple[float, ...]
    seconds: float


def frames_dir(pvd: str | Path) -> Path:
    """The folder of a series' .vtu frames: the .pvd's path without its suffix (``a/dem.pvd`` -> ``a/dem``)."""
    pvd = Path(pvd)
    if pvd.suffix != ".pvd":
        raise ExportError(f"{pvd}: a series is written as a .pvd file (its frames go to the folder beside it)")
    return pvd.with_suffix("")


def velocity(position: np.ndarray, time: np.ndarray) -> np.ndarray:
    """Finite-difference velocity [T, N, D] (m/s) of positions [T, N, D] recorded at ``time`` [T] (s).

    Backward difference: frame t > 0 gets (x_t - x_{t-1}) / (time_t - time_{t-1}), the velocity over the
    interval that ends at it; frame 0 takes the forward difference of its first interval (the same value as
    frame 1). Computed in float64; a non-finite position gives a non-finite velocity at its frames.
    """
    x = np.asarray(position, np.float64)
    t = np.asarray(time, np.float64)
    if x.shape[0] < 2 or t.shape != (x.shape[0],):
        raise ExportError(f"velocity needs at least 2 frames and one time per frame, got positions {x.shape} "
                          f"and times {t.shape}")
    backward = np.diff(x, axis=0) / np.diff(t)[:, None, None]
    return np.concatenate([backward[:1], backward], axis=0)


def _xyz(values: np.ndarray) -> np.ndarray:
    """[N, D] vectors as [N, 3], z = 0 for D = 2."""
    values = np.asarray(values)
    return values if values.shape[1] == 3 else np.pad(values, ((0, 0), (0, 3 - values.shape[1])))


def check_truth(traj: h5md.Trajectory, truth: h5md.Trajectory, what: str = "trajectory",
                truth_what: str = "truth") -> None:
    """Refuse a truth that is not the same particles over the same frames as ``traj``; names both."""
    if truth.n_particles != traj.n_particles:
        raise ExportError(f"{what} has {traj.n_particles} particles but {truth_what} has {truth.n_particles}: "
                          f"a rollout is scored against the sim it was rolled out from")
    if truth.dim != traj.dim:
        raise ExportError(f"{what} is {traj.dim}D but {truth_what} is {truth.dim}D")
    if truth.n_frames != traj.n_frames or not np.allclose(truth.time, traj.time, rtol=1e-9, atol=0):
        raise ExportError(f"{what} has {traj.n_frames} frames (t = {traj.time[0]:.6g}..{traj.time[-1]:.6g} s) but "
                          f"{truth_what} has {truth.n_frames} (t = {truth.time[0]:.6g}..{truth.time[-1]:.6g} s): "
                          f"the frame times must match")
    for name in ("species", "radius", "kinematic"):
        if not np.array_equal(np.asarray(getattr(traj, name)), np.asarray(getattr(truth, name))):
            raise ExportError(f"{what} and {truth_what} have the same particle count but different {name}: "
                              f"not the same particles")


def point_data(traj: h5md.Trajectory, frame: int, vel: np.ndarray,
               truth: h5md.Trajectory | None = None) -> dict[str, np.ndarray]:
    """The point data of one frame: particle index, species, radius, mass, kinematic flag, velocity [N, 3]
    (``vel`` is the frame's [N, D] velocity), every property by name, and with a truth the rollout error:
    the distance to the truth's position (m) and that distance in the particle's radii."""
    radius = np.asarray(traj.radius)
    data = {
        "id": np.arange(traj.n_particles, dtype=np.int32),
        "type": np.asarray(traj.species, np.int32),
        "radius": radius,
        "mass": np.asarray(traj.mass),
        "kinematic": np.asarray(traj.kinematic, np.uint8),
        "velocity": _xyz(vel),
    }
    if traj.properties is not None:
        for column, name in enumerate(traj.property_names):
            key = name if name not in (*BASE_FIELDS, *ERROR_FIELDS) else f"property_{name}"
            data[key] = np.asarray(traj.properties)[:, column]
    if truth is not None:
        error = np.linalg.norm(np.asarray(traj.position[frame], np.float64)
                               - np.asarray(truth.position[frame], np.float64), axis=-1)
        data["error"] = error
        data["error_radii"] = error / np.asarray(radius, np.float64)
    return data


def write_pvd(path: Path, entries: list[tuple[float, str]]) -> None:
    """A ParaView collection (.pvd) listing ``(time, file)`` entries, files relative to the .pvd's folder."""
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    collection = ET.SubElement(root, "Collection")
    for t, file in entries:
        ET.SubElement(collection, "DataSet", timestep=repr(float(t)), group="", part="0", file=file)
    ET.indent(root)
    ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)


def read_pvd(path: str | Path) -> list[tuple[float, Path]]:
    """The ``(time, file)`` entries of a .pvd, files resolved against its folder."""
    path = Path(path)
    root = ET.parse(path).getroot()
    return [(float(d.get("timestep")), path.parent / d.get("file")) for d in root.iter("DataSet")]


def export(traj: h5md.Trajectory, pvd: str | Path, truth: h5md.Trajectory | None = None,
           every: int = 1) -> Series:
    """Write ``traj`` as the ParaView series ``pvd`` (every ``every``-th recorded frame from the first).

    Velocities are finite differences over the recorded frames (:func:`velocity`), whatever ``every`` is.
    With ``truth`` (the DEM sim a rollout was made from), every frame also carries the rollout error.
    """
    start = time.perf_counter()
    pvd = Path(pvd)
    folder = frames_dir(pvd)
    if isinstance(every, bool) or not isinstance(every, int | np.integer) or every < 1:
        raise ExportError(f"every must be a positive whole number of frames, got {every!r}")
    if truth is not None:
        check_truth(traj, truth)
    vel = velocity(traj.position, traj.time)
    frames = tuple(range(0, traj.n_frames, every))
    cells = [("vertex", np.arange(traj.n_particles, dtype=np.int64)[:, None])]
    width = max(6, len(str(traj.n_frames - 1)))
    entries = []
    with atomic_outputs() as output:            # the frames and the .pvd replace the old series together
        with output(folder) as tmp_folder:
            tmp_folder.mkdir()
            for frame in frames:
                name = f"frame_{frame:0{width}d}.vtu"
                mesh = meshio.Mesh(_xyz(traj.position[frame]), cells,
                                   point_data=point_data(traj, frame, vel[frame], truth))
                mesh.write(tmp_folder / name, file_format="vtu")
                entries.append((float(traj.time[frame]), f"{folder.name}/{name}"))
        with output(pvd) as tmp_pvd:
            write_pvd(tmp_pvd, entries)
    return Series(pvd, folder, frames, tuple(t for t, _ in entries), time.perf_counter() - start)


def export_file(path: str | Path, pvd: str | Path, truth: str | Path | None = None, every: int = 1) -> Series:
    """Read the H5MD file ``path`` (non-finite positions of a blown-up rollout admitted, written as NaN) and,
    if given, the DEM file ``truth``, then :func:`export`. Errors name the files."""
    traj = h5md.read(path, allow_nonfinite=True)
    reference = None
    if truth is not None:
        reference = h5md.read(truth)
        check_truth(traj, reference, str(path), f"the truth {truth}")
    return export(traj, pvd, reference, every)
