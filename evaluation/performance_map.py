"""Where the surrogate pays (docs/performance.md, "The map"): per test sim, the headline surrogate's time per frame
against the DEM contenders it is compared with, beside the DEM sub-steps each of those needs per frame.

The speed-up of the surrogate on a sim is the DEM's time per frame over its own. The DEM's time per frame is its
sub-steps per frame n times its cost per step c (both the sim's, from the engine's own loop timing); the
surrogate's time per frame t does not depend on n. So on every sim the surrogate pays (speed-up at least 1) exactly
when n is at least the break-even n* = t / c, and the speed-up is n / n*: a scene's sims lie on the line
speed-up = n / n* when c and t are the same for all of them, and the map shows which side of n* each sim is on.

Compared per sim, from results/<scene>/performance.csv (evaluation/performance.py): the DEM contender that is as
accurate as the surrogate on the rollout MSE and every scene metric (``as accurate``: the performance report's
headline match over the scene's sims), the fastest as accurate on the MSE alone (``as accurate by MSE``) and the DEM
setting of the data (``reference``). A match that does not exist has no rows.
"""

from __future__ import annotations

import json

import pandas as pd

#: the comparisons of a map: its label -> the performance.csv column naming the DEM contender (None: the reference;
#: FASTEST: the fastest stable DEM contender whatever its error, beside the matches: the DEM's own error at another
#: step or stiffness is its chaos, which the matches, rerunning the DEM from t = 0, count against it)
FASTEST = "fastest DEM"
MATCHES = {"as accurate": "matched_dem", "as accurate by MSE": "matched_dem_by_mse", "reference": None,
           FASTEST: FASTEST}
COLUMNS = ("sim", "match", "dem_contender", "particles", "moving", "dem_steps_per_frame", "dem_ms_per_frame",
           "surrogate", "surrogate_ms_per_frame", "speedup", "break_even_steps", "pays")


def _per_sim(row: pd.Series) -> dict:
    text = row.get("per_sim")
    if not isinstance(text, str) or not text:
        raise ValueError(f"performance.csv: contender {row['contender']!r} has no per_sim timings (a table written "
                         "before they were recorded): rerun the performance stage")
    return json.loads(text)


def _fastest_dem(table: pd.DataFrame) -> str | None:
    """The stable DEM contender with the least time per rollout (None: no timed one)."""
    dem = table[table["kind"] == "dem"]
    if "stable" in dem:
        dem = dem[dem["stable"].astype(bool)]
    dem = dem[dem["seconds_per_rollout"].notna()] if "seconds_per_rollout" in dem else dem.iloc[:0]
    return str(dem.loc[dem["seconds_per_rollout"].idxmin(), "contender"]) if len(dem) else None


def sim_map(table: pd.DataFrame, main: str, reference: str) -> pd.DataFrame:
    """The map's rows (:data:`COLUMNS`): per comparison of :data:`MATCHES` and test sim, the DEM contender's sub-steps
    and milliseconds per frame, the surrogate's, the speed-up, the break-even sub-steps n* = (surrogate s per frame) /
    (DEM s per step) and whether the surrogate pays there (speed-up at least 1)."""
    rows = table.set_index("contender", drop=False)
    if main not in rows.index:
        raise ValueError(f"performance.csv has no surrogate contender {main!r} (performance.main)")
    surrogate = _per_sim(rows.loc[main])
    out = []
    fastest = _fastest_dem(table)
    for label, column in MATCHES.items():
        name = reference if column is None else fastest if column == FASTEST else rows.at[main, column]
        if not isinstance(name, str) or not name or name not in rows.index:
            continue
        dem = _per_sim(rows.loc[name])
        for sim in sorted(set(surrogate) & set(dem)):
            d, s = dem[sim], surrogate[sim]
            speedup = d["seconds_per_frame"] / s["seconds_per_frame"]
            out.append({"sim": sim, "match": label, "dem_contender": name, "particles": d["particles"],
                        "moving": d["moving"], "dem_steps_per_frame": d["steps_per_frame"],
                        "dem_ms_per_frame": 1000.0 * d["seconds_per_frame"], "surrogate": main,
                        "surrogate_ms_per_frame": 1000.0 * s["seconds_per_frame"], "speedup": speedup,
                        "break_even_steps": s["seconds_per_frame"] / d["seconds_per_dem_step"],
                        "pays": bool(speedup >= 1.0)})
    return pd.DataFrame(out, columns=list(COLUMNS))


def _verdict(pays: pd.Series) -> str:
    """``pays`` on every sim, on none, or on k of n."""
    if pays.all():
        return "pays"
    return "does not pay" if not pays.any() else f"pays on {int(pays.sum())} of {len(pays)} sims"


def pays_row(scene: str, sims: pd.DataFrame) -> dict:
    """One scene's row of the pays table from its map: the closest DEM comparison it has (as accurate on every
    measure, else by the MSE, else the data's setting), the medians over its test sims of the particles, the DEM's
    sub-steps and time per frame, the surrogate's, the break-even, and the speed-up with its range; beside it the
    median speed-up over the fastest DEM contender whatever its error."""
    match = next(m for m in MATCHES if (sims["match"] == m).any())
    part = sims[sims["match"] == match]
    fastest = sims[sims["match"] == FASTEST]
    return {"fastest_contender": str(fastest["dem_contender"].iloc[0]) if len(fastest) else "",
            "speedup_vs_fastest": float(fastest["speedup"].median()) if len(fastest) else float("nan"),
            "scene": scene, "sims": len(part), "match": match, "dem_contender": str(part["dem_contender"].iloc[0]),
            "particles": float(part["particles"].median()),
            "dem_steps_per_frame": float(part["dem_steps_per_frame"].median()),
            "dem_steps_min": float(part["dem_steps_per_frame"].min()),
            "dem_steps_max": float(part["dem_steps_per_frame"].max()),
            "dem_ms_per_frame": float(part["dem_ms_per_frame"].median()),
            "surrogate_ms_per_frame": float(part["surrogate_ms_per_frame"].median()),
            "break_even_steps": float(part["break_even_steps"].median()),
            "speedup": float(part["speedup"].median()), "speedup_min": float(part["speedup"].min()),
            "speedup_max": float(part["speedup"].max()), "verdict": _verdict(part["pays"].astype(bool))}


def pays_table(maps: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """The pays table: a row per scene (:func:`pays_row`), in the order given; a scene whose map is empty (no
    comparison could be made) is refused by name."""
    for scene, sims in maps.items():
        if sims.empty:
            raise ValueError(f"performance map of {scene!r} has no rows: no DEM contender could be compared")
    return pd.DataFrame([pays_row(scene, sims) for scene, sims in maps.items()])
