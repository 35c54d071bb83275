"""The sweep table: one row per simulation with every concrete DEM parameter and its seed.

Each simulation draws its parameters from its own generator seeded by (seed, index), so a row
never changes when sims are added, and the same config gives a bit-identical table. The scene says
what is swept (Scene.draw); every other physical key of its section is copied into each row
(Scene.row_params).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from generators import scenes

SPLITS = ("train", "valid", "test")


def split_counts(n: int, fractions: list[float]) -> list[int]:
    """The number of sims of each split (train, valid, test) of ``n``: every non-empty fraction gets at least one
    sim when n >= 3, the rest rounded (the config's check of the split uses this rule too)."""
    counts = [int(round(f * n)) for f in fractions]
    for i in range(3):
        if n >= 3 and fractions[i] > 0 and counts[i] == 0:
            counts[i] = 1
    while sum(counts) > n:
        counts[int(np.argmax(counts))] -= 1
    while sum(counts) < n:
        counts[0] += 1
    return counts


def split_labels(n: int, fractions: list[float], seed: int) -> list[str]:
    """Seeded 7:2:1-style assignment of :func:`split_counts`."""
    counts = split_counts(n, fractions)
    labels = np.array(sum(([s] * c for s, c in zip(SPLITS, counts, strict=True)), []))
    order = np.random.default_rng([seed, 7]).permutation(n)
    return list(labels[np.argsort(order)])


def build(scene_name: str, cfg: dict) -> pd.DataFrame:
    """The sweep table of scene ``scene_name`` from its validated config section."""
    scene = scenes.get(scene_name)
    n = scene.sweep_size(cfg)
    labels = split_labels(n, cfg["split"], cfg["seed"])
    packings = scene.packing_keys_of(cfg)
    fixed = scene.row_params(cfg)
    rows = []
    for i in range(n):
        rng = np.random.default_rng([cfg["seed"], i])
        row = {"id": f"{scene.name}_{i:04d}", "split": labels[i], "seed": int(rng.integers(2**31 - 1))}
        swept = scene.draw(cfg, i, rng, packings)
        row.update(swept)
        row.update({k: v for k, v in fixed.items() if k not in swept})
        rows.append(row)
    scene.finish_sweep(rows, cfg)
    return pd.DataFrame(rows)
