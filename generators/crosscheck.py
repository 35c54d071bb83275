"""Cross-check of two engines: the same sweep rows run in LAMMPS and in YADE, each scene metric compared
over the sims (docs/crosscheck.md).

Granular flows are chaotic, so single trajectories are not compared: each sim gives one value per scene
metric (its value at the last frame, the deposit), and the two engines' distributions over the sims
are compared by their means. A metric passes when the engines' means differ by at most ``tolerance``
(relative to the larger magnitude of the two) or by at most their combined standard error
sqrt(s_a^2 / n_a + s_b^2 / n_b), where that is larger. Both bounds are in the table. A metric
undefined at a sim's last frame (a crater metric before anything is disturbed) leaves that sim out;
with fewer than two values in an engine the row says so and has no verdict. Beside each verdict stands
the DEM's own chaos: the relative difference of the configured engine's mean from its rerun of the
same rows from packings perturbed by ``crosscheck.perturbation`` radii.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from generators import h5md, scenes

COLUMNS = ("scene", "metric", "unit", "engine_a", "engine_b", "n_a", "n_b", "mean_a", "mean_b", "std_a", "std_b",
           "rel_diff", "tolerance", "combined_se", "allowed", "pass", "chaos_engine", "chaos_rel_diff", "note")


def metric_names(scene: str) -> tuple[str, ...]:
    """The scene's metrics the cross-check compares: those of positions (``names``) and the DEM-only ones
    of the sim's observables (``dem_names``, e.g. the shear scene's peak shear stress), where it has them."""
    metrics = scenes.get(scene).metrics
    return tuple(metrics.names) + tuple(getattr(metrics, "dem_names", ()))


def final_values(scene: str, files: list[Path], body_displacement: float | None = None) -> pd.DataFrame:
    """One row per sim: each scene metric at the sim's last frame, and each DEM-only metric of the sim."""
    metrics = scenes.get(scene).metrics
    rows = []
    for path in files:
        traj = h5md.read(path)
        values = metrics.for_trajectory(traj, body_displacement)(traj.position)
        row = {"sim": Path(path).stem, **{name: float(np.asarray(values[name])[-1]) for name in metrics.names}}
        if getattr(metrics, "dem_names", ()):
            row.update(metrics.dem_values(traj))
        rows.append(row)
    return pd.DataFrame(rows)


def _rel(a: float, b: float) -> float:
    scale = max(abs(a), abs(b))
    return abs(a - b) / scale if scale > 0 else 0.0


def compare(scene: str, engines: dict[str, list[Path]], tolerance: float, body_displacement: float | None = None,
            chaos: list[Path] | None = None) -> pd.DataFrame:
    """The cross-check table of ``scene`` from each engine's H5MD files (engine -> files, two engines).

    ``chaos``: the same sims rerun by one engine from perturbed packings; each metric then also has
    ``chaos_rel_diff``, the relative difference of that engine's mean from its own perturbed rerun's:
    the size of difference the DEM's chaos alone makes, beside ``rel_diff`` (no part of the verdict)."""
    if len(engines) != 2:
        raise ValueError(f"the cross-check compares two engines, got {sorted(engines)}")
    (a, files_a), (b, files_b) = sorted(engines.items())
    ids_a, ids_b = sorted(Path(f).stem for f in files_a), sorted(Path(f).stem for f in files_b)
    if ids_a != ids_b:
        raise ValueError(f"{scene}: the engines ran different sims ({a}: {ids_a}, {b}: {ids_b}); the cross-check "
                         "compares the same sweep rows")
    if len(ids_a) < 2:
        raise ValueError(f"{scene}: the cross-check needs at least 2 sims per engine for a spread, got {len(ids_a)}")
    va, vb = (final_values(scene, f, body_displacement) for f in (files_a, files_b))
    chaos_engine, vc = None, None
    if chaos:
        chaos_engine = str(h5md.read(chaos[0]).parameters["engine"])
        if sorted(Path(f).stem for f in chaos) != ids_a or chaos_engine not in engines:
            raise ValueError(f"{scene}: the chaos reruns must be the same sims ({ids_a}) in one of {sorted(engines)}")
        vc = final_values(scene, chaos, body_displacement)
    base = {a: va, b: vb}.get(chaos_engine)
    units = scenes.get(scene).metrics.units
    rows = []
    for name in metric_names(scene):
        xa, xb = va[name].to_numpy(float), vb[name].to_numpy(float)
        undefined = (f"undefined at the last frame in {int(np.isnan(xa).sum())} {a} and "
                     f"{int(np.isnan(xb).sum())} {b} sims")
        xa, xb = xa[np.isfinite(xa)], xb[np.isfinite(xb)]
        if min(len(xa), len(xb)) < 2:     # e.g. no crater yet: nothing to compare, said so rather than passed
            rows.append({"scene": scene, "metric": name, "unit": units.get(name, ""), "engine_a": a, "engine_b": b,
                         "n_a": len(xa), "n_b": len(xb), "tolerance": tolerance, "pass": None,
                         "note": undefined + "; fewer than 2 values in an engine, not compared"})
            continue
        ma, mb, sa, sb = xa.mean(), xb.mean(), xa.std(ddof=1), xb.std(ddof=1)
        scale = max(abs(ma), abs(mb))
        rel = _rel(ma, mb)
        chaos_rel = _rel(float(np.nanmean(base[name])), float(np.nanmean(vc[name]))) if vc is not None else None
        se = math.sqrt(sa**2 / len(xa) + sb**2 / len(xb))
        allowed = max(tolerance * scale, se)
        rows.append({"scene": scene, "metric": name, "unit": units.get(name, ""), "engine_a": a, "engine_b": b,
                     "n_a": len(xa), "n_b": len(xb), "mean_a": ma, "mean_b": mb, "std_a": sa, "std_b": sb,
                     "rel_diff": rel, "tolerance": tolerance, "combined_se": se, "allowed": allowed,
                     "pass": bool(abs(ma - mb) <= allowed), "chaos_engine": chaos_engine,
                     "chaos_rel_diff": chaos_rel,
                     "note": undefined if len(xa) < len(va) or len(xb) < len(vb) else ""})
    return pd.DataFrame(rows, columns=list(COLUMNS))


def transfer(same: pd.DataFrame, other: pd.DataFrame, trained_on: str, other_engine: str) -> pd.DataFrame:
    """Rollout MSE of one model on its own engine's test sims and on the other engine's (two evaluate tables)."""
    rows = []
    for engine, table in ((trained_on, same), (other_engine, other)):
        mse = table[(table["metric"] == "rollout MSE") & (table["sim"] == "all")]
        for _, r in mse.iterrows():
            rows.append({"trained_on": trained_on, "scored_on": engine, "method": r["method"],
                         "history": int(r["history"]), "rollout_mse": float(r["mse"]), "sims": int(r["n_sims"])})
    return pd.DataFrame(rows)
