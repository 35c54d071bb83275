"""The property-sensitivity test (article Fig. 14): does the surrogate move the soil the way the DEM does when
one material property changes and nothing else does?

For each test sim the DEM is rerun twice from the sim's own packing, with every sweep parameter kept and one
property (``evaluate.property_sensitivity.property``, a node property f_i of the model) set to a low and a high
value inside the swept range (``generators.property_sensitivity.values``). The surrogate rolls out both reruns
from their own first K frames, as every rollout does. The article marks the mean x of the particle positions at a late
frame of each run and compares the two; here, at the last recorded frame t_end:

    Delta = mean_i x_i(t_end; high) - mean_i x_i(t_end; low)       (moving particles i)

for the DEM (``dem_delta``) and for Graph-DEM (``graphdem_delta``). The test passes a sim when both have the
same sign and ``ratio = graphdem_delta / dem_delta`` is within the tolerance (issue target: 25 %). The size of
the DEM's signal is stated beside it: against the DEM's own chaos (the same Delta between the sim and its
DEM-ensemble rerun, ``chaos_delta``, when the ensemble exists) and against the soil's mean x motion over the
predicted window (``motion``, of the low run). Constant-velocity extrapolation of the two reruns (from the same K
frames, under the runtime switches and box of the model's rollouts) is scored by the same rule (``cv_delta``,
``cv_ratio``, ``cv_passed``): where it passes too, the change was already visible in the given frames, and the test
says little about the model.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from evaluation.baseline import Extrapolation
from evaluation.stored import read_ensemble, read_rollout
from generators import h5md
from surrogate import dataset


def mean_x(position: np.ndarray, kinematic: np.ndarray) -> np.ndarray:
    """Per frame: the mean x (first axis) of the moving particles; NaN on a frame with a non-finite one."""
    x = np.asarray(position, np.float64)[:, ~np.asarray(kinematic, bool), 0]
    return x.mean(axis=1)


@dataclass
class Pair:
    """One test sim's two reruns: truth and prediction, low and high property value."""

    sim: str
    low: float
    high: float
    truth_low: h5md.Trajectory
    truth_high: h5md.Trajectory
    predicted_low: np.ndarray          # [T, N, D]
    predicted_high: np.ndarray


def property_value(traj: h5md.Trajectory, name: str, path: Path) -> float:
    """The one value of node property ``name`` every particle of a rerun carries."""
    values = np.unique(dataset.property_values(traj, name))
    if len(values) != 1:
        raise ValueError(f"{path}: property {name!r} takes {len(values)} values over the particles; the property "
                         f"test sets one value per run")
    return float(values[0])


def read_pair(runs: tuple[Path, Path], sim: str, name: str, sha: str, history: int) -> Pair:
    """The pair of ``sim`` from the two run folders (each with sims/<sim>.h5 and rollouts/<sim>.h5), low first;
    refuses runs whose particles or frames differ, or whose values are not low < high."""
    truths, predictions, values = [], [], []
    for run in runs:
        path = Path(run) / "sims" / f"{sim}.h5"
        truth = h5md.read(path)
        predicted = read_rollout(Path(run) / "rollouts" / f"{sim}.h5", sha, history)
        if predicted.position.shape != truth.position.shape:
            raise ValueError(f"{run}/rollouts/{sim}.h5: shape {predicted.position.shape} differs from the rerun's "
                             f"{truth.position.shape}")
        truths.append(truth)
        predictions.append(np.asarray(predicted.position, np.float64))
        values.append(property_value(truth, name, path))
    if not np.array_equal(truths[0].kinematic, truths[1].kinematic) or truths[0].position.shape != \
            truths[1].position.shape:
        raise ValueError(f"{sim}: the two reruns ({runs[0]}, {runs[1]}) hold different particles; the "
                         f"property-sensitivity test needs the same packing in both")
    if not values[0] < values[1]:
        raise ValueError(f"{sim}: {name} is {values[0]:g} in {runs[0]} and {values[1]:g} in {runs[1]}; give the "
                         f"low value's run first")
    return Pair(sim, values[0], values[1], truths[0], truths[1], predictions[0], predictions[1])


def compare(dem: float, graphdem: float, chaos: float, tolerance: float) -> dict:
    """The comparison of one DEM change with Graph-DEM's: ratio, same sign, the signal against the chaos, and
    whether it passes (same sign, ratio within 1 +- tolerance)."""
    ratio = graphdem / dem if dem != 0 else float("nan")
    same_sign = bool(np.sign(dem) == np.sign(graphdem) and dem != 0)
    return {"dem_delta": dem, "graphdem_delta": graphdem, "ratio": ratio, "same_sign": same_sign,
            "chaos_delta": chaos, "signal_to_chaos": abs(dem) / chaos if chaos > 0 else float("nan"),
            "passes": same_sign and abs(ratio - 1.0) <= tolerance}


def score_pair(pair: Pair, history: int, tolerance: float, chaos: np.ndarray | None = None,
               chaos_truth: np.ndarray | None = None, extrapolate: Extrapolation | None = None) -> dict:
    """The row of one pair (module docstring); ``chaos`` and ``chaos_truth`` are the sim's DEM-ensemble rerun and
    the sim itself ([T, N, D] each), or None; ``extrapolate``: constant velocity under the model's runtime
    (default: none)."""
    kinematic = pair.truth_low.kinematic
    truth_low, truth_high = mean_x(pair.truth_low.position, kinematic), mean_x(pair.truth_high.position, kinematic)
    pred_low, pred_high = mean_x(pair.predicted_low, kinematic), mean_x(pair.predicted_high, kinematic)
    chaos_delta = float("nan")
    if chaos is not None and chaos_truth is not None:
        chaos_delta = float(abs(mean_x(chaos, kinematic)[-1] - mean_x(chaos_truth, kinematic)[-1]))
    dem = float(truth_high[-1] - truth_low[-1])
    result = compare(dem, float(pred_high[-1] - pred_low[-1]), chaos_delta, tolerance)
    extrapolate = extrapolate or Extrapolation()
    cv_low, cv_high = (mean_x(extrapolate(t, history), kinematic)[-1] for t in (pair.truth_low, pair.truth_high))
    return {"sim": pair.sim, "value_low": pair.low, "value_high": pair.high, "frame": len(truth_low) - 1,
            "history": history, **result, "motion": float(truth_low[-1] - truth_low[history - 1]),
            **_baseline(compare(dem, float(cv_high - cv_low), chaos_delta, tolerance))}


def _baseline(result: dict) -> dict:
    """Constant velocity's change, ratio and pass, named cv_*."""
    return {"cv_delta": result["graphdem_delta"], "cv_ratio": result["ratio"], "cv_passes": result["passes"]}


def summary(rows: pd.DataFrame, tolerance: float) -> dict:
    """The 'all' row: the Deltas averaged over the sims, their comparison, and how many sims pass."""
    first = rows.iloc[0]
    dem, chaos = float(rows["dem_delta"].mean()), float(rows["chaos_delta"].mean())
    result = compare(dem, float(rows["graphdem_delta"].mean()), chaos, tolerance)
    return {"sim": "all", "value_low": first["value_low"], "value_high": first["value_high"],
            "frame": int(first["frame"]), "history": int(first["history"]), **result,
            "motion": float(rows["motion"].mean()), "passes": f"{int(rows['passes'].sum())} of {len(rows)}",
            **_baseline(compare(dem, float(rows["cv_delta"].mean()), chaos, tolerance)),
            "cv_passes": f"{int(rows['cv_passes'].sum())} of {len(rows)}"}


def run(runs: tuple[Path, Path], sims: list[str], name: str, sha: str, history: int, tolerance: float,
        chaos: tuple[Path, Path] | None = None,
        extrapolate: Extrapolation | None = None) -> tuple[pd.DataFrame, list[Pair]]:
    """The table (one row per sim, then 'all') and the pairs; ``chaos`` is (the sims' folder, the DEM
    ensemble's folder) or None; ``extrapolate``: constant velocity under the model's runtime."""
    if not sims:
        raise ValueError("the property-sensitivity test needs at least one test sim")
    rows, pairs = [], []
    for sim in sims:
        pair = read_pair(runs, sim, name, sha, history)
        member = truth = None
        if chaos is not None:
            base = h5md.read(Path(chaos[0]) / f"{sim}.h5")
            member, truth = read_ensemble(Path(chaos[1]) / f"{sim}.h5", base), base.position
        rows.append(score_pair(pair, history, tolerance, member, truth, extrapolate))
        pairs.append(pair)
    table = pd.DataFrame(rows)
    table = pd.concat([table, pd.DataFrame([summary(table, tolerance)])], ignore_index=True)
    def yes_no(passes: pd.Series) -> list[str]:
        return [p if isinstance(p, str) else ("yes" if p else "no") for p in passes]

    passed = yes_no(table.pop("passes"))
    table.insert(table.columns.get_loc("motion") + 1, "passed", passed)
    table["cv_passed"] = yes_no(table.pop("cv_passes"))
    return table.assign(property=name, tolerance=tolerance, checkpoint_sha=sha), pairs
