"""Simulations held in memory as tensors, and the (sim, frame) index of training samples.

A training sample (article 5.4.3) is the history window ``p^{t-K+1..t}`` of one sim and the
next frame ``p^{t+1}``; every sim of T frames yields T - K samples (``t = K-1 .. T-2``). A model that
predicts B frames per call (``model.bundle``) has the next B frames as its target, and T - K - B + 1
samples per sim.
"""

from __future__ import annotations

import math
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


def data_files(data: list[Path]) -> list[Path]:
    """H5MD files named directly or found (``*.h5``, sorted) in the given folders; hidden files (a writer's
    temporaries, ``.<name>.tmp-<pid>.h5``) are not sims and are skipped."""
    files: list[Path] = []
    for item in data:
        item = Path(item)
        if item.is_dir():
            found = sorted(p for p in item.glob("*.h5") if not p.name.startswith("."))
            if not found:
                raise FileNotFoundError(f"{item}: no *.h5 files in this folder")
            files.extend(found)
        elif item.is_file():
            files.append(item)
        else:
            raise FileNotFoundError(f"{item}: no such file or folder")
    return files


def to_device(sim: Sim, device: torch.device) -> Sim:
    """The sim with its tensors on ``device`` (the sim itself where they are there already)."""
    if sim.position.device == device:
        return sim
    return replace(sim, position=sim.position.to(device), types=sim.types.to(device),
                   kinematic=sim.kinematic.to(device), props=None if sim.props is None else sim.props.to(device))


def sample_index(sims: list[Sim], history: int, bundle: int = 1) -> list[tuple[int, int]]:
    """Every (sim index, last history frame t) with the ``bundle`` next frames to predict
    (``t = K-1 .. T-1-B``: T - K - B + 1 samples per sim of T frames)."""
    index = []
    for s, sim in enumerate(sims):
        if sim.n_frames < history + bundle:
            raise ValueError(f"{sim.path}: {sim.n_frames} frames cannot give a history of {history} "
                             f"plus {bundle} target frame(s)")
        index.extend((s, t) for t in range(history - 1, sim.n_frames - bundle))
    return index


def sample_activity(sims: list[Sim], index: list[tuple[int, int]]) -> np.ndarray:
    """Each sample's activity: the mean over its moving particles of the squared target acceleration
    ``|p^{t+1} - 2 p^t + p^{t-1}|^2`` (dataset length units per frame squared), the quantity the training
    loss is made of. A sim with no moving particle has activity 0 in every sample."""
    activity = np.zeros(len(index))
    rows: dict[int, list[int]] = {}
    for i, (s, _) in enumerate(index):
        rows.setdefault(s, []).append(i)
    for s, mine in rows.items():
        moving = ~sims[s].kinematic
        if not bool(moving.any()):
            continue
        p = sims[s].position[:, moving].double()
        frames = torch.tensor([index[i][1] for i in mine])
        acceleration = p[frames + 1] - 2 * p[frames] + p[frames - 1]
        activity[mine] = (acceleration ** 2).sum(-1).mean(-1).numpy()
    return activity


def activity_weights(activity: np.ndarray, weight: float) -> torch.Tensor | None:
    """The probability weights ``1 + weight * a_s / mean(a)`` of drawing each sample s (``a``: its activity,
    :func:`sample_activity`); None for ``weight`` 0, which keeps the uniform epoch (every sample once). With
    ``weight`` > 0 a sample moving w times the mean activity is drawn ``(1 + weight w) / (1 + weight)`` times
    as often as the average sample, so the rare frames of an impact or a collapse, where the flow's
    accelerations are, are seen more often at the same number of steps."""
    if weight < 0 or not math.isfinite(weight):
        raise ValueError(f"train.activity_weight must be a finite number >= 0 (0: uniform sampling), not {weight}")
    if weight == 0:
        return None
    mean = float(np.mean(activity)) if len(activity) else 0.0
    if not mean > 0:
        return None                          # nothing moves: every sample is alike
    return torch.tensor(1.0 + weight * np.asarray(activity, np.float64) / mean)


def epoch_activity_weight(weight: float, final: float | None, epoch: int, epochs: int) -> float:
    """The activity weight of ``epoch`` (0-based) of ``epochs``: ``weight`` throughout when ``final`` is None,
    else linear from ``weight`` at the first epoch to ``final`` at the last (``train.activity_weight_final``):
    the early epochs see the busy samples more often, the late ones the quiet samples again."""
    if final is None or epochs <= 1:
        return float(weight)
    return float(weight + (final - weight) * epoch / (epochs - 1))


def epoch_order(n: int, weights: torch.Tensor | None, generator: torch.Generator) -> list[int]:
    """The sample order of one epoch of ``n`` draws: a permutation without ``weights``; with them, ``n``
    draws with replacement, each sample with probability proportional to its weight."""
    if weights is None:
        return torch.randperm(n, generator=generator).tolist()
    return torch.multinomial(weights, n, replacement=True, generator=generator).tolist()
