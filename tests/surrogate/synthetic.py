"""A small synthetic 2D dataset (no DEM engine): a dense cluster of moving discs falling onto a kinematic
floor, a few sims of a few frames, with its split table and stats.json, and tiny model configs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from generators import h5md
from surrogate import dataset

RADIUS = 1.6          # connectivity radius (m): about 8 senders per moving receiver, more in the cluster's core
MODEL = {"history": 3, "latent": 8, "hidden": 8, "message_passing": 2, "embed": 4, "mlp_layers": 2,
         "properties": []}
TRAIN = {"lr": 1e-3, "lr_final": None, "noise_std": 0.0, "mirror": False, "pushforward": 0.0, "pushforward_steps": 1,
         "ema_decay": None, "seed": 0, "checkpoint_every": 0, "valid_sims": None, "precision": "float32",
         "batch_size": 2, "epochs": 1, "patience": 1}


def write_sim(path: Path, seed: int, frames: int = 7) -> None:
    """36 moving discs on a jittered 6 x 6 lattice of spacing 0.9 m (senders within R: 4 to 12), falling with
    random accelerations (std 0.02 m per frame^2 per axis), and 14 kinematic floor discs below them."""
    rng = np.random.default_rng(seed)
    grid = np.stack(np.meshgrid(np.arange(6), np.arange(6)), -1).reshape(-1, 2) * 0.9 + [5.0, 4.0]
    start = grid + rng.uniform(-0.1, 0.1, grid.shape)
    velocity = np.cumsum(rng.normal(0, 0.02, (frames, *start.shape)) + [0.0, -0.01], axis=0)
    moving = start[None] + np.cumsum(velocity, axis=0)
    floor = np.stack([np.arange(14) * 0.8 + 3.0, np.full(14, 3.0)], -1)
    position = np.concatenate([moving, np.broadcast_to(floor, (frames, 14, 2))], axis=1)
    n = position.shape[1]
    kinematic = np.arange(n) >= 36
    h5md.write(path, h5md.Trajectory(
        position=position, time=np.arange(frames) * 0.1, step=np.arange(frames) * 100,
        species=np.where(kinematic, 0, 1), radius=np.full(n, 0.4), mass=np.ones(n), kinematic=kinematic,
        box_lower=np.zeros(2), box_upper=np.full(2, 16.0)))


def build(root: Path, splits: tuple[str, ...] = ("train", "train", "valid", "test")) -> dict:
    """The sims (one per entry of ``splits``), splits.csv and stats.json under ``root``; their paths."""
    ids = [f"syn_{i:02d}" for i in range(len(splits))]
    for i, name in enumerate(ids):
        write_sim(root / "sims" / f"{name}.h5", seed=i)
    table = dataset.split_table(pd.DataFrame({"id": ids, "split": list(splits)}), root / "sims")
    stats = dataset.build(table, root / "dataset", RADIUS)
    return {"root": root, "stats": stats, "stats_path": root / "dataset" / "stats.json",
            "splits": root / "dataset" / "splits.csv", "sims": root / "sims",
            "paths": {name: root / "sims" / f"{name}.h5" for name in ids},
            "split_of": dict(zip(ids, splits, strict=True))}
