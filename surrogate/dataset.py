"""A dataset of H5MD simulations: the split table and normalisation statistics.

Velocities and accelerations are finite differences of positions per frame (article eq. 1):
``v_t = p_t - p_{t-1}``, ``a_t = v_t - v_{t-1}``, in metres per frame (squared). Their mean and
standard deviation per axis over the moving (non-kinematic) particles of the train split only
are what the model is normalised with.

The statistics also count, at the connectivity radius R, every receiver's senders in the graph
(``neighbour_counts``; :mod:`surrogate.neighbours`): over every particle (kinematic ones included:
a cap applies to them too) of every frame but the last (the frames a graph is built on), in float32
positions as training reads them. Their largest value, 99th percentile, mean and histogram, and for
a given cap (the model config's ``max_neighbours``) the share of receivers it truncates and of edges
it drops, let a cap be chosen from the data.

For R itself they record the next-frame contacts of the train split (``next_frame_contacts``), the share a
graph of radius R misses (``contact_miss_rate``) and the floors R must exceed to miss at most 1 %, 0.1 %,
0.01 % and none of them (``contact_miss_floor``; :mod:`surrogate.contacts`).

A user-data set (any folder of H5MD sims, docs/user-data.md; :func:`build_user`) is split by
:func:`generators.user_data.split_table`; every one of its sims is read and must hold the frames a training
sample needs, R may be derived from the train split's radii (:func:`surrogate.derived.connectivity_radius`), and
stats.json records the folder and the split's settings under ``user_data`` (the evaluation then scores the
generic metrics only) and a derived R under ``derived``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from generators import h5md
from generators.atomic import atomic_path
from surrogate import derived as derived_rules
from surrogate.contacts import contact_distances, miss_floor, missed_at
from surrogate.neighbours import Histogram, check_cap, neighbour_counts

CONTACT_MISS_WARNING = 0.01      # `graphdem dataset` warns above this contact-miss rate of R on the train split
# stats.json's contact_miss_floor: the R above which at most this share of the train split's next-frame contacts is
# missed (a report, not a setting)
MISS_FLOOR_RATES = (1e-2, 1e-3, 1e-4, 0.0)


class _Moments:
    """Streaming per-axis mean and variance (Chan et al. parallel update)."""

    def __init__(self, dim: int):
        self.n = 0
        self.mean = np.zeros(dim)
        self.m2 = np.zeros(dim)

    def add(self, values: np.ndarray) -> None:
        values = values.reshape(-1, self.mean.size).astype(np.float64)
        if len(values) == 0:
            return
        n_b, mean_b = len(values), values.mean(axis=0)
        m2_b = ((values - mean_b) ** 2).sum(axis=0)
        delta = mean_b - self.mean
        total = self.n + n_b
        self.mean = self.mean + delta * n_b / total
        self.m2 = self.m2 + m2_b + delta**2 * self.n * n_b / total
        self.n = total

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(self.m2 / max(self.n, 1))


def property_values(traj: h5md.Trajectory, name: str) -> np.ndarray:
    """Per-particle values of a node property: ``radius`` or a column of the H5MD properties."""
    if name == "radius":
        return np.asarray(traj.radius, np.float64)
    if name in traj.property_names:
        return np.asarray(traj.properties, np.float64)[:, traj.property_names.index(name)]
    raise ValueError(f"node property {name!r} is not in the data: allowed 'radius' or one of "
                     f"{list(traj.property_names) or 'no stored properties'}")


def split_table(sweep: pd.DataFrame, sims_dir: Path) -> pd.DataFrame:
    return pd.DataFrame({"id": sweep["id"], "split": sweep["split"],
                         "path": [str(Path(sims_dir) / f"{i}.h5") for i in sweep["id"]]})


def frame_neighbours(traj: h5md.Trajectory, connectivity_radius: float) -> Histogram:
    """Receivers per neighbour count at R = ``connectivity_radius`` over the frames of ``traj`` a graph is
    built on (all but the last), in float32 positions (module docstring)."""
    position = np.asarray(traj.position, np.float32)
    histogram = Histogram()
    for frame in position[:-1]:
        histogram.add(neighbour_counts(frame, connectivity_radius, traj.kinematic))
    return histogram


def statistics(paths: list[Path], connectivity_radius: float, max_neighbours: int | None = None) -> dict:
    """Normalisation statistics of the train sims ``paths`` plus dataset metadata; the neighbour counts at
    R and what the cap ``max_neighbours`` (null: none) cuts of them (module docstring)."""
    if not paths:
        raise ValueError("the train split is empty: cannot compute normalisation statistics")
    cap = check_cap(max_neighbours, "max_neighbours")
    neighbours = Histogram()
    vel = acc = None
    meta = {}
    distances = []                       # per next-frame contact, its centre distance one frame earlier
    species = set()
    kinematic_species = set()
    props: dict[str, _Moments] = {}
    logged: set[str] = set()
    for path in tqdm(paths, desc="dataset statistics", unit="sim"):
        traj = h5md.read(path)
        if vel is None:
            vel, acc = _Moments(traj.dim), _Moments(traj.dim)
            meta = {"dim": traj.dim, "bounds": np.stack([traj.box_lower, traj.box_upper], 1).tolist(),
                    "frame_interval": float(np.median(np.diff(traj.time))),
                    "n_frames": traj.n_frames, "property_names": list(traj.property_names),
                    "scene": str(traj.parameters.get("scene", "unknown"))}
        elif traj.dim != meta["dim"]:
            raise ValueError(f"{path}: dimension {traj.dim} differs from the dataset's {meta['dim']}")
        elif str(traj.parameters.get("scene", "unknown")) != meta["scene"]:
            raise ValueError(f"{path}: scene {traj.parameters.get('scene')!r} differs from the dataset's "
                             f"{meta['scene']!r} (one dataset holds one scene)")
        moving = ~traj.kinematic
        distances.append(contact_distances(traj.position, traj.radius, traj.kinematic))
        neighbours.merge(frame_neighbours(traj, connectivity_radius))
        p = np.asarray(traj.position, np.float64)[:, moving]
        v = np.diff(p, axis=0)
        vel.add(v)
        acc.add(np.diff(v, axis=0))
        logs = set(traj.parameters.get("log_scaled_properties") or [])
        logged |= logs
        for name in ("radius", *traj.property_names):
            values = property_values(traj, name)[moving]
            props.setdefault(name, _Moments(1)).add(np.log(values) if name in logs else values)
        species.update(np.unique(traj.species).tolist())
        kinematic_species.update(np.unique(traj.species[traj.kinematic]).tolist())
    floor = 1e-12
    distances = np.concatenate(distances)
    missed = missed_at(distances, connectivity_radius)
    return {
        **meta,
        "velocity_mean": vel.mean.tolist(), "velocity_std": np.maximum(vel.std, floor).tolist(),
        "acceleration_mean": acc.mean.tolist(), "acceleration_std": np.maximum(acc.std, floor).tolist(),
        "velocity_unit": "m/frame", "acceleration_unit": "m/frame^2",
        "connectivity_radius": float(connectivity_radius),
        # the share of the next frame's contacts whose pair is R or farther apart in the frame the graph is built
        # on (surrogate/contacts.py): contacts the model cannot see coming
        "contact_miss_rate": missed / len(distances) if len(distances) else None,
        "next_frame_contacts": len(distances),
        # the radius R must exceed to miss at most that share of them (surrogate/contacts.py, miss_floor)
        "contact_miss_floor": {f"{rate:g}": miss_floor(distances, rate) if len(distances) else None
                               for rate in MISS_FLOOR_RATES},
        "n_types": int(max(species)) + 1, "kinematic_species": sorted(int(s) for s in kinematic_species),
        "n_train_sims": len(paths), "n_velocity_samples": int(vel.n),
        # every receiver's senders within R (itself not counted) over the train frames a graph is built on, and
        # the share of receivers and edges the cap max_neighbours cuts (surrogate/neighbours.py)
        "neighbour_counts": neighbours.summary(cap),
        # node properties f_i (radius and the H5MD properties) over the moving train particles; those the
        # data marks as log-scaled (a modulus spans decades) are normalised as ln(value)
        "property_stats": {name: {"mean": float(m.mean[0]), "std": float(max(m.std[0], floor)),
                                  "log": name in logged} for name, m in props.items()},
    }


def build(splits: pd.DataFrame, out_dir: Path, connectivity_radius: float, max_neighbours: int | None = None,
          extra: dict | None = None) -> dict:
    """Write splits.csv (id, split, path) and stats.json (train split only) into ``out_dir``; ``max_neighbours``
    is the neighbour cap whose cut the stats report (null: none); ``extra``: keys stats.json records beside."""
    missing = {"id", "split", "path"} - set(splits.columns)
    if missing:
        raise ValueError(f"a split table needs the columns id, split and path; missing {sorted(missing)}")
    splits = splits[["id", "split", "path"]]
    train = [Path(p) for p in splits.loc[splits["split"] == "train", "path"]]
    stats = statistics(train, connectivity_radius, max_neighbours)
    stats["splits"] = splits["split"].value_counts().to_dict()
    stats.update(extra or {})
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with atomic_path(out_dir / "splits.csv") as tmp:
        splits.to_csv(tmp, index=False)
    with atomic_path(out_dir / "stats.json") as tmp:
        tmp.write_text(json.dumps(stats, indent=2))
    return stats


def mean_moving_radius(paths: list[Path]) -> float:
    """The mean radius of the moving particles of the sims ``paths``, pooled over them (as stats.json's
    ``property_stats.radius.mean``); only each sim's first two frames are read."""
    radii = []
    for path in paths:
        traj = h5md.read(path, frames=slice(0, 2))
        radii.append(np.asarray(traj.radius, np.float64)[~np.asarray(traj.kinematic, bool)])
    pooled = np.concatenate(radii) if radii else np.zeros(0)
    if not len(pooled):
        raise ValueError(f"no moving particle in the {len(paths)} train sims: nothing to learn, and no mean diameter "
                         "to derive the connectivity radius from")
    return float(pooled.mean())


def check_frames(paths: list[Path], min_frames: int) -> None:
    """Every sim of ``paths`` is a readable H5MD file of at least ``min_frames`` frames (a history and the frames
    predicted after it); raise ValueError naming the first that is not."""
    for path in tqdm(paths, desc="check sims", unit="sim"):
        frames = h5md.read(path).n_frames
        if frames < min_frames:
            raise ValueError(f"{path}: {frames} frames; a training sample is the model's history and the frame(s) "
                             f"predicted after it, so each sim needs at least {min_frames} (model.history + "
                             f"model.bundle): shorten the history or leave the sim out")


def build_user(folder: Path, out_dir: Path, fractions: list[float], seed: int, connectivity_radius: float | None,
               diameters: float, min_frames: int, max_neighbours: int | None = None) -> dict:
    """The dataset of a user-data folder (module docstring): splits.csv and stats.json in ``out_dir``; R is
    ``connectivity_radius``, or where None, ``diameters`` mean diameters of the train split's moving particles."""
    from generators import user_data
    table = user_data.split_table(folder, fractions, seed)
    check_frames([Path(p) for p in table["path"]], min_frames)
    extra = {"user_data": {"folder": str(folder), "fractions": list(fractions), "seed": int(seed)}}
    if connectivity_radius is None:
        radius = mean_moving_radius([Path(p) for p in table.loc[table["split"] == "train", "path"]])
        connectivity_radius = derived_rules.connectivity_radius(radius, diameters)
        extra["derived"] = {"connectivity_radius": {
            "rule": "connectivity_diameters x mean diameter of the train split's moving particles",
            "connectivity_diameters": float(diameters), "mean_diameter": 2.0 * radius}}
    return build(table, out_dir, connectivity_radius, max_neighbours, extra)
