"""The sweep table: one row per simulation with every concrete DEM parameter and its seed.

Each simulation draws its parameters from its own generator seeded by (seed, index), so a row
never changes when sims are added, and the same config gives a bit-identical table.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from generators.scenes import meteorite, shear, slide
from generators.scenes.packing import packing_key

SPLITS = ("train", "valid", "test")
SCENE_PARAMS = {
    "slide": ("domain", "gravity", "bedrock_profile", "soil_surface", "bedrock_radius", "radius",
              "density", "young", "kt_over_kn", "restitution", "friction", "rolling_friction",
              "weak_friction", "weak_rolling_friction", "dt_safety", "dt", "frames", "record_start",
              "frame_interval", "max_overlap", "max_energy_gain", "engine"),
    "meteorite": ("domain", "gravity", "radius", "bed_depth", "meteorite_radius", "density", "young", "kt_over_kn",
                  "restitution", "friction", "rolling_friction", "dt_safety", "dt", "frames", "contact_frame",
                  "frame_interval", "max_overlap", "max_energy_gain", "engine"),
    "shear": ("box", "gravity", "radius", "wall_radius", "wall_spacing", "density", "kt_over_kn", "restitution",
              "friction", "dt_safety", "dt", "shear_speed", "frames", "max_overlap", "failure_band", "engine"),
}


def split_labels(n: int, fractions: list[float], seed: int) -> list[str]:
    """Seeded 7:2:1-style assignment; every non-empty fraction gets at least one sim when n >= 3."""
    counts = [int(round(f * n)) for f in fractions]
    for i in range(3):
        if n >= 3 and fractions[i] > 0 and counts[i] == 0:
            counts[i] = 1
    while sum(counts) > n:
        counts[int(np.argmax(counts))] -= 1
    while sum(counts) < n:
        counts[0] += 1
    labels = np.array(sum(([s] * c for s, c in zip(SPLITS, counts, strict=True)), []))
    order = np.random.default_rng([seed, 7]).permutation(n)
    return list(labels[np.argsort(order)])


def slide_sweep(cfg: dict) -> pd.DataFrame:
    rows = []
    labels = split_labels(cfg["n_sims"], cfg["split"], cfg["seed"])
    keys = [packing_key(slide.packing_params(cfg, j)) for j in range(cfg["n_packings"])]
    for i in range(cfg["n_sims"]):
        rng = np.random.default_rng([cfg["seed"], i])
        row = {"id": f"slide_{i:04d}", "split": labels[i], "seed": int(rng.integers(2**31 - 1))}
        for name in ("weak_base", "weak_thickness", "weak_dip"):
            lo, hi = cfg["sweep"][name]
            row[name] = round(float(rng.uniform(lo, hi)), 4)
        if cfg["sweep"]["weak_friction"] is not None:
            lo, hi = cfg["sweep"]["weak_friction"]
            weak_friction = round(float(rng.uniform(lo, hi)), 4)
        else:
            weak_friction = cfg["weak_friction"]
        packing = int(rng.integers(cfg["n_packings"]))
        row["packing"] = keys[packing]
        for name in SCENE_PARAMS["slide"]:
            row[name] = cfg[name]
        row["weak_friction"] = weak_friction
        rows.append(row)
    return pd.DataFrame(rows)


def _grid(lo: float, hi: float, n: int) -> list[float]:
    return [round(float(v), 6) for v in (np.linspace(lo, hi, n) if n > 1 else [0.5 * (lo + hi)])]


def _grid_sweep(scene: str, cfg: dict, axes: dict[str, list[float]], packing: str) -> pd.DataFrame:
    """One row per combination of the ``axes`` values (the first axis varies slowest)."""
    names = list(axes)
    combos = np.array(np.meshgrid(*axes.values(), indexing="ij")).reshape(len(names), -1).T
    labels = split_labels(len(combos), cfg["split"], cfg["seed"])
    rows = []
    for i, values in enumerate(combos):
        rng = np.random.default_rng([cfg["seed"], i])
        row = {"id": f"{scene}_{i:04d}", "split": labels[i], "seed": int(rng.integers(2**31 - 1)),
               **{n: float(v) for n, v in zip(names, values, strict=True)}, "packing": packing}
        row.update({name: cfg[name] for name in SCENE_PARAMS[scene]})
        rows.append(row)
    return pd.DataFrame(rows)


def meteorite_sweep(cfg: dict) -> pd.DataFrame:
    """The impact angle x speed grid (article 5.1: 31 x 31 at paper scale); every sim shares one bed."""
    sw = cfg["sweep"]
    axes = {"angle": _grid(*sw["angle"], sw["n_angles"]), "speed": _grid(*sw["speed"], sw["n_speeds"])}
    return _grid_sweep("meteorite", cfg, axes, packing_key(meteorite.packings(cfg)[0]))


def shear_sweep(cfg: dict) -> pd.DataFrame:
    """The soil modulus x shear displacement grid; every sim shares one packing. ``domain_displacement``
    (the largest displacement) fixes the same data bounds for every sim."""
    axes = {"young": shear.young_values(cfg), "displacement": [float(d) for d in cfg["sweep"]["displacements"]]}
    table = _grid_sweep("shear", cfg, axes, packing_key(shear.packings(cfg)[0]))
    table["domain_displacement"] = max(axes["displacement"])
    return table


BUILDERS = {"slide": slide_sweep, "meteorite": meteorite_sweep, "shear": shear_sweep}


def build(scene: str, cfg: dict) -> pd.DataFrame:
    """The sweep table of ``scene`` from its validated config section."""
    if scene not in BUILDERS:
        raise ValueError(f"unknown scene {scene!r}; known: {', '.join(BUILDERS)}")
    return BUILDERS[scene](cfg)
