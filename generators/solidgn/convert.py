"""Convert a Solid-GN dataset folder (``train/``, ``valid/``, ``test/`` of pickles plus
``metadata.json``) into H5MD sims and a split table.

Particle type 0 is the fixed wall: kinematic, never predicted. Types 1 and 2 are soil. Every
particle keeps its radius (Slide-Small has heterogeneous radii; the model can take it as the
node property f_i). Frames are numbered; their times are frame index x the metadata's ``dt``.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from generators import h5md
from generators.atomic import atomic_path
from generators.solidgn.safe_pickle import load

SPLITS = ("train", "valid", "test")
SCENE = "solidgn"


def _array(data: dict, key: str, path: Path, ndim: int) -> np.ndarray:
    if key not in data:
        raise ValueError(f"{path}: missing array {key!r}; a Solid-GN trajectory has particle_type, particle_r, "
                         f"particle_m and position")
    value = data[key]
    if not isinstance(value, np.ndarray) or value.ndim != ndim:
        raise ValueError(f"{path}: {key} must be a {ndim}-dimensional numpy array, got "
                         f"{type(value).__name__} of shape {getattr(value, 'shape', None)}")
    if value.dtype.kind not in "fiu":
        raise ValueError(f"{path}: {key} must hold numbers, got dtype {value.dtype}")
    if not np.all(np.isfinite(value)):
        raise ValueError(f"{path}: {key} has non-finite values")
    return value


def trajectory(path: Path, metadata: dict, name: str) -> h5md.Trajectory:
    """One Solid-GN pickle as a validated H5MD trajectory."""
    data = load(path)
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a dict of arrays, got {type(data).__name__}")
    position = _array(data, "position", path, 3)
    types = _array(data, "particle_type", path, 1)
    radius = _array(data, "particle_r", path, 1)
    mass = _array(data, "particle_m", path, 1)
    t, n, d = position.shape
    if t < 2 or n < 1:
        raise ValueError(f"{path}: position has shape {position.shape}; a trajectory needs at least 2 frames and "
                         f"1 particle")
    if d != metadata["dim"] or any(len(a) != n for a in (types, radius, mass)):
        raise ValueError(f"{path}: position has shape {position.shape} but particle_type/r/m have "
                         f"{len(types)}/{len(radius)}/{len(mass)} entries and the metadata's dim is {metadata['dim']}")
    if not np.array_equal(types, np.round(types)) or types.min() < 0:
        raise ValueError(f"{path}: particle_type must hold non-negative integers")
    bounds = np.asarray(metadata["bounds"], float)
    kinematic = types == 0
    return h5md.Trajectory(
        position=position.astype(np.float32), time=np.arange(t) * float(metadata["dt"]), step=np.arange(t),
        species=types.astype(np.int32), radius=radius, mass=mass, kinematic=kinematic,
        box_lower=bounds[:, 0], box_upper=bounds[:, 1], boundary=("none",) * d,
        parameters={"scene": SCENE, "dataset": name, "source_file": str(path), "units": "m (Solid-GN)",
                    "frame_interval": float(metadata["dt"]), "connectivity_radius":
                    float(metadata.get("default_connectivity_radius", np.nan)),
                    "species_names": {"0": "fixed wall", "1": "soil type 1", "2": "soil type 2"},
                    "solidgn_metadata": metadata})


def read_metadata(path: Path) -> dict:
    """A Solid-GN metadata.json, checked: dim 2 or 3, bounds [[lo, hi]] per axis, dt > 0 (all finite)."""
    try:
        meta = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not valid JSON: {exc}") from exc
    if not isinstance(meta, dict):
        raise ValueError(f"{path}: expected a JSON object with dim, bounds and dt, got {type(meta).__name__}")
    dim = meta.get("dim")
    if dim not in (2, 3) or isinstance(dim, bool):
        raise ValueError(f"{path}: 'dim' must be 2 or 3, got {dim!r}")
    try:
        bounds = np.asarray(meta.get("bounds"), float)
        dt = float(meta.get("dt"))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{path}: 'bounds' must be [[lo, hi]] per axis and 'dt' a number: {exc}") from exc
    if bounds.shape != (dim, 2) or not np.all(np.isfinite(bounds)) or not np.all(bounds[:, 1] > bounds[:, 0]):
        raise ValueError(f"{path}: 'bounds' must be {dim} finite [lo, hi] pairs with lo < hi, "
                         f"got {meta.get('bounds')!r}")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"{path}: 'dt' must be a positive number, got {meta.get('dt')!r}")
    radius = meta.get("default_connectivity_radius", 1.0)
    if isinstance(radius, bool) or not isinstance(radius, int | float) or not (np.isfinite(radius) and radius > 0):
        raise ValueError(f"{path}: 'default_connectivity_radius' must be a positive number, got {radius!r}")
    return meta


def _number(path: Path) -> tuple[int, str]:
    match = re.match(r"(\d+)$", path.stem)
    return (int(match[1]) if match else 10**9, path.stem)


def import_dataset(src: str | Path, dest: str | Path, progress: bool = True,
                   limits: dict[str, int | None] | None = None) -> pd.DataFrame:
    """Convert every split found in ``src``; write ``dest/sims/<split>_<n>.h5`` and ``dest/splits.csv``.

    ``limits`` keeps only the first N trajectories (by number) of a split; None or absent: all.
    """
    limits = dict(limits or {})
    unknown = sorted(set(limits) - set(SPLITS))
    if unknown:
        raise ValueError(f"limits name unknown splits {unknown}; allowed: {list(SPLITS)}")
    src, dest = Path(src), Path(dest)
    meta_path = src / "metadata.json"
    if not meta_path.is_file():
        raise FileNotFoundError(f"{src}: no metadata.json; expected a Solid-GN dataset folder "
                                f"(metadata.json and train/, valid/, test/ of .pkl files)")
    metadata = read_metadata(meta_path)
    rows = []
    with atomic_path(dest) as tmp:          # all or nothing: a refused pickle leaves no half import behind
        tmp.mkdir()
        for split in SPLITS:
            files = sorted((p for p in (src / split).glob("*.pkl") if not p.name.startswith(".")), key=_number) \
                if (src / split).is_dir() else []
            if limits.get(split) is not None:
                files = files[: int(limits[split])]
            for path in tqdm(files, desc=f"import {src.name}/{split}", unit="sim", disable=not progress):
                sim_id = f"{split}_{_number(path)[1]}"
                h5md.write(tmp / "sims" / f"{sim_id}.h5", trajectory(path, metadata, src.name))
                rows.append({"id": sim_id, "split": split, "path": str(dest / "sims" / f"{sim_id}.h5"),
                             "source": str(path)})
        if not any(r["split"] == "train" for r in rows):
            raise FileNotFoundError(f"{src}: no train/*.pkl files")
        table = pd.DataFrame(rows)
        table.to_csv(tmp / "splits.csv", index=False)
        (tmp / "metadata.json").write_text(json.dumps(metadata, indent=2))
    return table
