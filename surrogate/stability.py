"""Surrogate stress tests: long rollouts from a perturbed history, and the same rollout in three
precisions (docs/performance.md, "Stability").

A long rollout runs ``length`` times the recorded window; beyond the last recorded frame the
kinematic particles stay where the data left them. It reports, never hides: the first
non-finite frame, particles that leave the dataset's bounds, overlaps above the DEM's limit,
the growth of the error per step over the recorded window, and the largest speed at the end
(a landslide should come to rest, not drift or vibrate).
"""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd
import torch

from generators.blowup import max_overlap_fraction
from surrogate import runtime as rt
from surrogate.noise import random_walk_position_noise
from surrogate.rollout import rollout, rollout_mse
from surrogate.samples import Sim
from surrogate.simulator import LearnedSimulator


def error_growth(mse: np.ndarray) -> float:
    """Geometric mean growth of the rollout MSE per predicted frame, (mse[-1] / mse[0])^(1/(n-1))."""
    mse = np.asarray(mse, float)
    if len(mse) < 2 or not np.all(np.isfinite(mse)) or mse[0] <= 0:
        return float("nan")
    return float((mse[-1] / mse[0]) ** (1.0 / (len(mse) - 1)))


def long_rollout(simulator: LearnedSimulator, runtime: rt.Runtime, sim: Sim, length: int, noise_std: float,
                 seed: int, max_overlap: float) -> dict:
    """One row: a rollout ``length`` x the recorded window from a history with random-walk noise."""
    k = simulator.history
    moving = ~sim.kinematic
    generator = torch.Generator().manual_seed(seed)
    noise = random_walk_position_noise(k, sim.position.shape[1], sim.position.shape[2], noise_std, moving, generator)
    result = rollout(simulator, sim, n_frames=length * sim.n_frames, runtime=runtime, start=sim.position[:k] + noise)
    position = np.asarray(result.position, np.float64)
    end = position.shape[0] if result.first_nonfinite is None else result.first_nonfinite
    finite = position[:end, moving.numpy()]
    lower, upper = simulator.lower.double().cpu().numpy(), simulator.upper.double().cpu().numpy()
    outside = ((finite < lower) | (finite > upper)).any(axis=-1)           # [T, N_moving]
    radius, kinematic = np.asarray(sim.traj.radius, float), sim.kinematic.numpy()
    overlaps = np.array([max_overlap_fraction(x, radius, kinematic) for x in position[k:end]])
    recorded = min(sim.n_frames, end)
    mse = rollout_mse(position[:recorded], sim.position.numpy()[:recorded], moving.numpy(), k)
    tail = max(2, (end - k) // 10)
    speed = np.linalg.norm(np.diff(finite[-tail:], axis=0), axis=-1) if end - k >= 2 else np.array([np.nan])
    causes, frames = [], []
    if result.first_nonfinite is not None:
        causes.append("non-finite position")
        frames.append(result.first_nonfinite)
    if outside.any():
        first = int(np.argmax(outside.any(axis=1)))
        causes.append(f"{int(outside.any(axis=0).sum())} particles left the bounds, the first at frame {first}")
        frames.append(first)
    return {
        "test": "surrogate_long_rollout", "sim": sim.id, "setting": f"{length}x recorded window, history noise "
        f"{noise_std:g} m per frame", "factor": float(length), "stable": not causes,
        "frame": min(frames) if frames else np.nan, "cause": "; ".join(causes),
        "n_frames": int(position.shape[0]), "nonfinite_frame": result.first_nonfinite,
        "escaped_particles": int(outside.any(axis=0).sum()),
        "first_escape_frame": int(np.argmax(outside.any(axis=1))) if outside.any() else np.nan,
        "frames_over_overlap_limit": int((overlaps > max_overlap).sum()),
        "max_overlap": float(overlaps.max()) if len(overlaps) else np.nan,
        "mse_recorded": float(mse.mean()) if len(mse) else np.nan, "mse_growth_per_step": error_growth(mse),
        "final_max_speed": float(np.max(speed)) if speed.size else np.nan, "wall_seconds": result.seconds,
    }


def precision_rows(simulator: LearnedSimulator, base: rt.Runtime, sim: Sim) -> list[dict]:
    """The recorded-window rollout in float64, float32 and bfloat16: each one's MSE against the
    data and its largest position difference from the float64 rollout."""
    rollouts = {}
    for precision in rt.PRECISIONS:
        runtime = rt.Runtime(**{**base.as_dict(), "precision": precision})
        prepared = rt.apply(copy.deepcopy(simulator), runtime)
        rollouts[precision] = rollout(prepared, sim, runtime=runtime)
    reference = np.asarray(rollouts["float64"].position, np.float64)
    moving, k = ~sim.kinematic.numpy(), simulator.history
    rows = []
    for precision, result in rollouts.items():
        position = np.asarray(result.position, np.float64)
        difference = np.abs(position[k:, moving] - reference[k:, moving])
        rows.append({
            "test": "surrogate_precision", "sim": sim.id, "setting": precision,
            "stable": result.first_nonfinite is None,
            "frame": np.nan if result.first_nonfinite is None else result.first_nonfinite, "cause": "",
            "mse_recorded": float(rollout_mse(position, sim.position.numpy(), moving, k).mean()),
            "max_difference_vs_float64": float(np.nanmax(difference)),
            "mean_difference_vs_float64": float(np.nanmean(difference)),
            "wall_seconds": result.seconds,
        })
    return rows


def surrogate_report(simulator: LearnedSimulator, runtime: rt.Runtime, sims: list[Sim], lengths: list[int],
                     noise_std: float, seed: int, max_overlap: float) -> pd.DataFrame:
    prepared = rt.apply(copy.deepcopy(simulator), runtime)
    rows = []
    for s, sim in enumerate(sims):
        for length in lengths:
            rows.append(long_rollout(prepared, runtime, sim, int(length), noise_std, seed + s, max_overlap))
        rows.extend(precision_rows(simulator, runtime, sim))
    return pd.DataFrame(rows)
