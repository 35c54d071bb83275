"""Cross-check of the engines: the same sweep rows run in each registered engine (LAMMPS and YADE), each
scene metric compared over the sims for each pair of engines (docs/crosscheck.md).

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

import itertools
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


def _same_rows(scene: str, engines: dict[str, list[Path]]) -> list[str]:
    """The sim ids every engine ran (sorted), refused unless all ran the same ones, at least 2 of them."""
    ids = {name: sorted(Path(f).stem for f in files) for name, files in sorted(engines.items())}
    (a, ids_a), *others = ids.items()
    for b, ids_b in others:
        if ids_a != ids_b:
            raise ValueError(f"{scene}: the engines ran different sims ({a}: {ids_a}, {b}: {ids_b}); the "
                             "cross-check compares the same sweep rows")
    if len(ids_a) < 2:
        raise ValueError(f"{scene}: the cross-check needs at least 2 sims per engine for a spread, got {len(ids_a)}")
    return ids_a


def _chaos(scene: str, chaos: list[Path] | None, ids: list[str], engines: dict,
           body_displacement: float | None) -> tuple[str | None, pd.DataFrame | None]:
    """The engine of the chaos reruns and their final values (None, None without reruns)."""
    if not chaos:
        return None, None
    engine = str(h5md.read(chaos[0]).parameters["engine"])
    if sorted(Path(f).stem for f in chaos) != ids or engine not in engines:
        raise ValueError(f"{scene}: the chaos reruns must be the same sims ({ids}) in one of {sorted(engines)}")
    return engine, final_values(scene, chaos, body_displacement)


def compare(scene: str, engines: dict[str, list[Path]], tolerance: float, body_displacement: float | None = None,
            chaos: list[Path] | None = None) -> pd.DataFrame:
    """The cross-check table of ``scene`` from each engine's H5MD files (engine -> files, two engines or more):
    one row per pair of engines (in name order) and scene metric.

    ``chaos``: the same sims rerun by one engine from perturbed packings; each metric then also has
    ``chaos_rel_diff``, the relative difference of that engine's mean from its own perturbed rerun's:
    the size of difference the DEM's chaos alone makes, beside ``rel_diff`` (no part of the verdict)."""
    if len(engines) < 2:
        raise ValueError(f"the cross-check compares two engines or more, got {sorted(engines)}")
    ids = _same_rows(scene, engines)
    values = {name: final_values(scene, files, body_displacement) for name, files in sorted(engines.items())}
    chaos_engine, vc = _chaos(scene, chaos, ids, engines, body_displacement)
    chaos_rel = {name: None if vc is None else _rel(float(np.nanmean(values[chaos_engine][name])),
                                                    float(np.nanmean(vc[name]))) for name in metric_names(scene)}
    rows = [_row(scene, name, (a, values[a]), (b, values[b]), tolerance, (chaos_engine, chaos_rel[name]))
            for a, b in itertools.combinations(sorted(engines), 2) for name in metric_names(scene)]
    return pd.DataFrame(rows, columns=list(COLUMNS))


def _row(scene: str, name: str, engine_a: tuple[str, pd.DataFrame], engine_b: tuple[str, pd.DataFrame],
         tolerance: float, chaos: tuple[str | None, float | None]) -> dict:
    """One metric of one pair of engines (each its name and final values): the means, spreads and verdict, and
    ``chaos``: the chaos engine and its relative difference from its own reruns (None, None without reruns)."""
    (a, va), (b, vb) = engine_a, engine_b
    chaos_engine, chaos_rel = chaos
    unit = scenes.get(scene).metrics.units.get(name, "")
    xa, xb = va[name].to_numpy(float), vb[name].to_numpy(float)
    undefined = (f"undefined at the last frame in {int(np.isnan(xa).sum())} {a} and "
                 f"{int(np.isnan(xb).sum())} {b} sims")
    xa, xb = xa[np.isfinite(xa)], xb[np.isfinite(xb)]
    if min(len(xa), len(xb)) < 2:     # e.g. no crater yet: nothing to compare, said so rather than passed
        return {"scene": scene, "metric": name, "unit": unit, "engine_a": a, "engine_b": b,
                "n_a": len(xa), "n_b": len(xb), "tolerance": tolerance, "pass": None,
                "note": undefined + "; fewer than 2 values in an engine, not compared"}
    ma, mb, sa, sb = xa.mean(), xb.mean(), xa.std(ddof=1), xb.std(ddof=1)
    se = math.sqrt(sa**2 / len(xa) + sb**2 / len(xb))
    allowed = max(tolerance * max(abs(ma), abs(mb)), se)
    return {"scene": scene, "metric": name, "unit": unit, "engine_a": a, "engine_b": b,
            "n_a": len(xa), "n_b": len(xb), "mean_a": ma, "mean_b": mb, "std_a": sa, "std_b": sb,
            "rel_diff": _rel(ma, mb), "tolerance": tolerance, "combined_se": se, "allowed": allowed,
            "pass": bool(abs(ma - mb) <= allowed), "chaos_engine": chaos_engine, "chaos_rel_diff": chaos_rel,
            "note": undefined if len(xa) < len(va) or len(xb) < len(vb) else ""}


def transfer(same: pd.DataFrame, other: pd.DataFrame, trained_on: str, other_engine: str) -> pd.DataFrame:
    """Rollout MSE of one model on its own engine's test sims and on the other engine's (two evaluate tables)."""
    rows = []
    for engine, table in ((trained_on, same), (other_engine, other)):
        mse = table[(table["metric"] == "rollout MSE") & (table["sim"] == "all")]
        for _, r in mse.iterrows():
            rows.append({"trained_on": trained_on, "scored_on": engine, "method": r["method"],
                         "history": int(r["history"]), "rollout_mse": float(r["mse"]), "sims": int(r["n_sims"])})
    return pd.DataFrame(rows)
