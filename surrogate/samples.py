"""Simulations held in memory as tensors, and the (sim, frame) index of training samples.

A training sample (article 5.4.3) is the history window ``p^{t-K+1..t}`` of one sim and the
next frame ``p^{t+1}``; every sim of T frames yields T - K samples (``t = K-1 .. T-2``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch

from generators import h5md
from surrogate.dataset import property_values


@dataclass
class Sim:
    """One H5MD trajectory as tensors, with the node properties the model was configured with."""

    id: str
    path: Path
    position: torch.Tensor          # [T, N, D] float32, metres
    types: torch.Tensor             # [N] long
    kinematic: torch.Tensor         # [N] bool
    props: torch.Tensor | None      # [N, F] normalised, None when the model takes no property
    traj: h5md.Trajectory           # the file as read (time, radius, parameters, ...)

    @property
    def n_frames(self) -> int:
        return int(self.position.shape[0])


def normalised_properties(traj: h5md.Trajectory, names: list[str], stats: dict) -> torch.Tensor | None:
    """Properties z-scored with the train-split statistics (``log`` first where stats say so)."""
    if not names:
        return None
    columns = []
    for name in names:
        s = stats.get("property_stats", {}).get(name)
        if s is None:
            raise ValueError(f"node property {name!r} has no statistics in stats.json; "
                             f"known: {sorted(stats.get('property_stats', {}))}")
        values = property_values(traj, name)
        if s.get("log"):
            values = np.log(values)
        columns.append((values - s["mean"]) / s["std"])
    return torch.tensor(np.stack(columns, axis=1), dtype=torch.float32)


def check_scene(path: Path, traj: h5md.Trajectory, stats: dict, allow_other_scene: bool = False) -> None:
    """Refuse a sim the model was not trained for: another dimension, species beyond its types, or (unless
    ``allow_other_scene``) another scene or other kinematic species than its training data."""
    if traj.dim != stats["dim"]:
        raise ValueError(f"{path}: dimension {traj.dim} differs from the model's {stats['dim']}")
    if int(traj.species.max()) >= stats["n_types"]:
        raise ValueError(f"{path}: species {int(traj.species.max())} is beyond the {stats['n_types']} types "
                         f"the model was trained with (0..{stats['n_types'] - 1})")
    if allow_other_scene:
        return
    scene, trained = str(traj.parameters.get("scene", "unknown")), stats.get("scene")
    if trained is not None and scene != trained:
        raise ValueError(f"{path}: a {scene} sim, but the model was trained on {trained} data; give "
                         f"--allow-other-scene to score it anyway")
    kinematic = sorted(int(s) for s in np.unique(traj.species[traj.kinematic]))
    if "kinematic_species" in stats and not set(kinematic) <= set(stats["kinematic_species"]):
        raise ValueError(f"{path}: kinematic species {kinematic}, but the model was trained with kinematic species "
                         f"{stats['kinematic_species']}; give --allow-other-scene to score it anyway")


def load_sim(path: str | Path, stats: dict, property_names: list[str] | None = None,
             traj: h5md.Trajectory | None = None, allow_other_scene: bool = False) -> Sim:
    path = Path(path)
    traj = traj if traj is not None else h5md.read(path)
    check_scene(path, traj, stats, allow_other_scene)
    return Sim(id=path.stem, path=path, position=torch.tensor(np.asarray(traj.position, np.float32)),
               types=torch.tensor(np.asarray(traj.species), dtype=torch.long),
               kinematic=torch.tensor(np.asarray(traj.kinematic, bool)),
               props=normalised_properties(traj, list(property_names or []), stats), traj=traj)


def to_device(sim: Sim, device: torch.device) -> Sim:
    """The sim with its tensors on ``device`` (the sim itself where they are there already)."""
    if sim.position.device == device:
        return sim
    return replace(sim, position=sim.position.to(device), types=sim.types.to(device),
                   kinematic=sim.kinematic.to(device), props=None if sim.props is None else sim.props.to(device))


def sample_index(sims: list[Sim], history: int) -> list[tuple[int, int]]:
    """Every (sim index, last history frame t) with a next frame to predict."""
    index = []
    for s, sim in enumerate(sims):
        if sim.n_frames < history + 1:
            raise ValueError(f"{sim.path}: {sim.n_frames} frames cannot give a history of {history} "
                             f"plus a target frame")
        index.extend((s, t) for t in range(history - 1, sim.n_frames - 1))
    return index
