"""The stability stage's DEM test: one sim of the sweep at time steps that are multiples of the
stable limit.

Each run goes through the same ``simulate`` as the dataset (and so through every blow-up
detector of :mod:`generators.blowup`); a run that blows up must name the sim, the frame and
the cause, and leave nothing behind. The raw output of the runs is scratch: only the report is
kept.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import numpy as np
import pandas as pd

from generators import blowup, convert, engine, scenes


def dem_time_steps(scene_name: str, row: dict, packing: Path, factors: list[float], scratch: Path) -> pd.DataFrame:
    """One report row per factor f: the sim run with dt = f x stable limit (``dt_safety = f``, no
    refusal: finding the unstable steps is the point), stable or blown up, with frame and cause."""
    scene = scenes.get(scene_name)
    scratch = Path(scratch)
    rows = []
    for factor in factors:
        out = scratch / f"dt_x{factor:g}"
        start = time.perf_counter()
        record = {"test": "dem_time_step", "sim": row["id"], "setting": f"dt = {factor:g} x stable limit",
                  "factor": float(factor)}
        try:
            rec = engine.simulate(scene, {**row, "dt": None, "dt_safety": float(factor)}, packing, out)
            traj = convert.trajectory(out)
            kinematic = np.asarray(traj.kinematic, bool)
            record.update(stable=True, frame=np.nan, cause="", dt=rec.dt, dt_limit=rec.dt_limit,
                          steps_per_frame=rec.steps_per_frame,
                          max_overlap=max(blowup.max_overlap_fraction(np.asarray(x, float), traj.radius, kinematic)
                                          for x in traj.position))
        except blowup.BlowUp as exc:
            record.update(stable=False, frame=exc.frame, cause=exc.cause)
        record["wall_seconds"] = time.perf_counter() - start
        # a failed run must leave no folder and no temporary (atomic_path's ".<name>.tmp-<pid>...")
        record["left_behind"] = int(out.exists() and not record["stable"]) + sum(1 for _ in scratch.glob(".*tmp-*"))
        rows.append(record)
        shutil.rmtree(out, ignore_errors=True)
    return pd.DataFrame(rows)
