"""The shear test's stress, predicted: the peak shear stress and the stress curve of each test sim, read by the
shear-stress readout (:mod:`evaluation.shear_stress`) from Graph-DEM's rollout, beside the DEM.

Per test sim, over the predicted frames (K .. T-1; the rollout is given the first K):

* ``dem_peak``: the DEM's peak of its ``shear_stress`` observable (the truth);
* ``readout_peak``: the readout applied to the DEM's own frames (the readout's error alone);
* ``graphdem_peak``: the readout applied to Graph-DEM's rollout (the surrogate's prediction);
* ``cv_peak``: the readout applied to constant-velocity extrapolation from the same K frames, under the runtime
  switches and box of the model's rollouts;
* ``ensemble_peak``: the first DEM ensemble member's own observable (the sim rerun from its state at the last
  given frame, perturbed: the DEM's chaos, a second sample of the truth);
* ``coulomb_peak``: no model at all, the Mohr-Coulomb guess a geotechnical engineer makes from the training tests:
  tau = sigma_n mu, mu the train sims' mean peak stress ratio (their peaks of tau / sigma_n over the same
  frames, averaged), along the train sims' mean curve of tau / sigma_n scaled to that peak (:func:`coulomb`).
  A stress predicted from Graph-DEM's frames is worth having where it beats this floor.

Each ``*_error`` is (peak - dem_peak) / dem_peak, each ``*_rmse`` the RMS difference of the curve from the DEM's
over the predicted frames (Pa); ``passed``: |graphdem_error| <= tolerance (issue target: 10 %). The ``all`` row
holds the mean absolute errors, the mean RMSEs and the number of sims passed.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from evaluation import shear_stress
from evaluation.baseline import Extrapolation
from evaluation.stored import read_rollout
from generators import h5md

COMPARATORS = ("readout", "graphdem", "cv", "ensemble", "coulomb")


@dataclass
class Curves:
    """One test sim's shear stress per frame (Pa): the DEM's observable and each comparator's."""

    sim: str
    displacement: np.ndarray          # [T] m, the lower half's shear displacement
    dem: np.ndarray                   # [T]
    predicted: dict[str, np.ndarray]  # comparator -> [T] (NaN where undefined)


def _peak(curve: np.ndarray, history: int) -> float:
    tail = np.asarray(curve, float)[history:]
    return float(np.nanmax(tail)) if np.isfinite(tail).any() else float("nan")


def coulomb(train_ratio: list, normal_stress: float, history: int) -> np.ndarray:
    """[T] Pa: the Mohr-Coulomb floor (module docstring) for a sim at ``normal_stress``, from the train sims' curves
    of tau / sigma_n ([S][T], stored with the readout): sigma_n mu s(t) / max s, s the mean curve, mu the mean
    of the curves' peaks, both over frames ``history`` .. T-1, so that the curve's peak is sigma_n mu there."""
    ratio = np.asarray(train_ratio, np.float64)
    if ratio.ndim != 2 or ratio.shape[1] <= history or not np.isfinite(ratio).all():
        raise ValueError(f"the readout's train stress ratios have shape {ratio.shape} (finite: "
                         f"{bool(np.isfinite(ratio).all())}); the Coulomb floor needs one finite curve per train sim "
                         f"longer than K = {history}")
    shape = ratio.mean(axis=0)
    return normal_stress * float(ratio[:, history:].max(axis=1).mean()) * shape / float(shape[history:].max())


def curves(model: shear_stress.StressReadout, meta: dict, traj: h5md.Trajectory, rollout: np.ndarray,
           history: int, ensemble: h5md.Trajectory | None, extrapolate: Extrapolation | None = None) -> Curves:
    """The DEM's curve and the comparators' of one test sim (module docstring); ``meta`` is the readout's;
    ``extrapolate``: constant velocity under the model's runtime (default: none)."""
    if "train_stress_ratio" not in meta:
        raise ValueError("the stress readout predates the Coulomb floor (no train_stress_ratio in its metadata): "
                         "refit it, e.g. snakemake -c2 results/<scene>/shear_stress.csv -R shear_stress_readout")
    truth = shear_stress.Sample.from_trajectory(traj)
    if not np.isfinite(truth.shear_stress).all():
        raise ValueError(f"sim {truth.id}: no shear_stress observable; rerun its DEM (the shear scene writes it)")
    floor = coulomb(meta["train_stress_ratio"], truth.normal_stress, history)
    if len(floor) != len(truth.shear_stress):
        raise ValueError(f"sim {truth.id} has {len(truth.shear_stress)} frames, the readout's train sims "
                         f"{len(floor)}: the Coulomb floor compares frame by frame")
    cutoff = float(meta["cutoff"])
    predicted = {
        "readout": shear_stress.read(model, truth, cutoff),
        "graphdem": shear_stress.read(model, shear_stress.Sample.from_trajectory(traj, rollout), cutoff),
        "cv": shear_stress.read(model, shear_stress.Sample.from_trajectory(
            traj, (extrapolate or Extrapolation())(traj, history)), cutoff),
        "ensemble": (np.asarray(ensemble.observables["shear_stress"], float) if ensemble is not None
                     else np.full(len(truth.shear_stress), np.nan)),
        "coulomb": floor,
    }
    return Curves(truth.id, np.asarray(traj.observables.get("shear_displacement", np.arange(len(traj.time))), float),
                  truth.shear_stress, predicted)


def score(curve: Curves, history: int, tolerance: float, normal_stress: float, young: float) -> dict:
    """One sim's row (module docstring)."""
    dem_peak = _peak(curve.dem, history)
    row = {"sim": curve.sim, "normal_stress": normal_stress, "young": young, "history": history,
           "dem_peak": dem_peak}
    for name in COMPARATORS:
        peak = _peak(curve.predicted[name], history)
        diff = (np.asarray(curve.predicted[name], float) - curve.dem)[history:]
        row[f"{name}_peak"] = peak
        row[f"{name}_error"] = (peak - dem_peak) / dem_peak
        row[f"{name}_rmse"] = float(np.sqrt(np.mean(diff ** 2))) if np.isfinite(diff).all() else float("nan")
    row["passed"] = bool(abs(row["graphdem_error"]) <= tolerance)
    return row


def summary(rows: pd.DataFrame, tolerance: float) -> dict:
    """The ``all`` row: mean |error| and mean RMSE per comparator, sims passed."""
    out = {"sim": "all", "history": int(rows["history"].iloc[0]), "dem_peak": float(rows["dem_peak"].mean()),
           "passed": f"{int(rows['passed'].sum())} of {len(rows)} (within {tolerance:.0%})"}
    for name in COMPARATORS:
        out[f"{name}_peak"] = float(rows[f"{name}_peak"].mean())
        out[f"{name}_error"] = float(rows[f"{name}_error"].abs().mean())
        out[f"{name}_rmse"] = float(rows[f"{name}_rmse"].mean())
    return out


def run(readout: Path, sims: list[Path], rollouts: Path, sha: str, history: int, tolerance: float,
        ensemble: Path | None = None, extrapolate: Extrapolation | None = None) -> tuple[pd.DataFrame, list[Curves]]:
    """The table (a row per sim, then ``all``) and the curves, from the test sims' files, the rollouts made by the
    checkpoint of digest ``sha`` (``rollouts/<id>.h5``), optionally the DEM ensemble's first member
    (``ensemble/<id>.h5``), and constant velocity under the model's runtime (``extrapolate``; default: none)."""
    model, meta = shear_stress.load(readout)
    rows, all_curves = [], []
    for path in sims:
        traj = h5md.read(path)
        sim = str(traj.parameters["id"])
        rollout = read_rollout(rollouts / f"{sim}.h5", sha, history)
        member = h5md.read(ensemble / f"{sim}.h5") if ensemble is not None else None
        curve = curves(model, meta, traj, np.asarray(rollout.position, np.float64), history, member, extrapolate)
        all_curves.append(curve)
        rows.append(score(curve, history, tolerance, float(traj.parameters["normal_stress"]),
                          float(traj.parameters["young"])))
    table = pd.DataFrame(rows)
    return pd.concat([table, pd.DataFrame([summary(table, tolerance)])], ignore_index=True), all_curves
