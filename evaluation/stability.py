"""Surrogate stability tests: long rollouts from a perturbed history, and the same rollout in three
precisions (docs/performance.md, "Stability").

A long rollout runs ``length`` times the recorded window; beyond the last recorded frame the
kinematic particles stay where the data left them. It reports, never hides: the first
non-finite frame, particles that leave the dataset's box (or, with the runtime switch
``keep_in_domain``, how many times a particle was put back on a box face; with ``contact_correction``,
how many times a particle was stopped at a kinematic particle it passed and a pair was pushed apart), the overlap
distribution, the particles that passed a wall (the plausibility measure ``Through wall``: reported, not part of
the envelope below) and the kinetic energy per frame, the growth of the error per step over the recorded
window, the largest speed at the end (a flow should come to rest, not drift or vibrate), and the
first frame that leaves the physical envelope.

**The physical envelope** of a frame: every position finite; every moving particle inside the box;
the largest overlap at most the scene's ``max_overlap`` (the DEM's own blow-up limit, a fraction of
the smaller radius); the moving particles' kinetic energy (translational, from the position
difference to the previous frame, as for the data) at most ``energy_envelope`` times the largest of
the recorded data. Beyond the recorded window no boundary moves any more, so a granular flow can only
lose energy: growth beyond the data's peak is energy the rollout made up.
"""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd
import torch

from evaluation.metrics.plausibility import OVERLAP_QUANTILE, kinetic_energy, through_wall
from generators.blowup import overlap_fractions
from surrogate import runtime as rt
from surrogate.noise import random_walk_position_noise
from surrogate.rollout import rollout, rollout_mse
from surrogate.samples import Sim
from surrogate.simulator import LearnedSimulator


def frame_table(position: np.ndarray, sim: Sim, lower: np.ndarray, upper: np.ndarray, start: int, max_overlap: float,
                energy_limit: float) -> pd.DataFrame:
    """Per frame from ``start``: kinetic energy, the overlap distribution (max and 99th percentile of
    overlap / smaller radius), moving particles outside the box and through a wall since the frame before,
    and whether the frame is inside the physical envelope (module docstring) and, if not, why."""
    traj, moving = sim.traj, ~sim.kinematic.numpy()
    radius, kinematic = np.asarray(traj.radius, float), sim.kinematic.numpy()
    energy = kinetic_energy(position, traj.mass, moving, frame_interval(traj))
    rows = []
    for t in range(start, position.shape[0]):
        x = position[t]
        finite = bool(np.isfinite(x).all())
        overlaps = overlap_fractions(x, radius, kinematic) if finite else np.zeros(0)
        outside = int(((x[moving] < lower) | (x[moving] > upper)).any(axis=-1).sum()) if finite else 0
        passed = through_wall(position[t - 1], x, radius, kinematic) \
            if t > 0 and finite and np.isfinite(position[t - 1]).all() else 0
        worst = float(overlaps.max()) if len(overlaps) else 0.0
        causes = [c for c, bad in (("non-finite", not finite), ("outside the box", outside > 0),
                                   (f"overlap above {max_overlap:g} radii", worst > max_overlap),
                                   (f"kinetic energy above {energy_limit:.3g}", finite and energy[t] > energy_limit))
                  if bad]
        rows.append({"frame": t, "kinetic_energy": energy[t], "max_overlap": worst,
                     f"p{OVERLAP_QUANTILE}_overlap": float(np.percentile(overlaps, OVERLAP_QUANTILE)) if len(overlaps)
                     else 0.0, "outside": outside, "through_wall": passed, "in_envelope": not causes,
                     "envelope_cause": "; ".join(causes)})
    return pd.DataFrame(rows)


def frame_interval(traj) -> float:
    """Seconds between recorded frames."""
    return float(np.median(np.diff(np.asarray(traj.time, float))))


def data_energy_peak(sim: Sim) -> float:
    """The largest kinetic energy of the moving particles over the sim's recorded frames."""
    return float(np.nanmax(kinetic_energy(sim.traj.position, sim.traj.mass, ~sim.kinematic.numpy(),
                                          frame_interval(sim.traj))))


def error_growth(mse: np.ndarray) -> float:
    """Geometric mean growth of the rollout MSE per predicted frame, (mse[-1] / mse[0])^(1/(n-1))."""
    mse = np.asarray(mse, float)
    if len(mse) < 2 or not np.all(np.isfinite(mse)) or mse[0] <= 0:
        return float("nan")
    return float((mse[-1] / mse[0]) ** (1.0 / (len(mse) - 1)))


def long_rollout(simulator: LearnedSimulator, runtime: rt.Runtime, sim: Sim, length: int, noise_std: float,
                 seed: int, max_overlap: float, energy_envelope: float = float("inf")) -> tuple[dict, pd.DataFrame]:
    """One report row and its per-frame table: a rollout ``length`` x the recorded window from a history
    with random-walk noise."""
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
    peak = data_energy_peak(sim)
    frames = frame_table(position[: end + 1 if result.first_nonfinite is not None else end], sim, lower, upper, k,
                         max_overlap, energy_envelope * peak)
    frames.insert(0, "length", int(length))
    frames.insert(0, "sim", sim.id)
    overlaps = frames.loc[frames["frame"] < end, "max_overlap"].to_numpy()
    recorded = min(sim.n_frames, end)
    mse = rollout_mse(position[:recorded], sim.position.numpy()[:recorded], moving.numpy(), k)
    tail = max(2, (end - k) // 10)
    speed = np.linalg.norm(np.diff(finite[-tail:], axis=0), axis=-1) if end - k >= 2 else np.array([np.nan])
    causes, first = [], []
    if result.first_nonfinite is not None:
        causes.append("non-finite position")
        first.append(result.first_nonfinite)
    if outside.any():
        escape = int(np.argmax(outside.any(axis=1)))
        causes.append(f"{int(outside.any(axis=0).sum())} particles left the bounds, the first at frame {escape}")
        first.append(escape)
    leaving = frames[~frames["in_envelope"].astype(bool)]
    row = {
        "test": "surrogate_long_rollout", "sim": sim.id, "setting": f"{length}x recorded window, history noise "
        f"{noise_std:g} m per frame", "factor": float(length), "stable": not causes,
        "frame": min(first) if first else np.nan, "cause": "; ".join(causes),
        "n_frames": int(position.shape[0]), "nonfinite_frame": result.first_nonfinite,
        "escaped_particles": int(outside.any(axis=0).sum()),
        "first_escape_frame": int(np.argmax(outside.any(axis=1))) if outside.any() else np.nan,
        "clamped_particle_steps": int(result.timing.get("clamped", 0)),
        "stopped_particle_steps": int(result.timing.get("stopped", 0)),
        "corrected_pair_steps": int(result.timing.get("corrected", 0)),
        "through_wall_particle_steps": int(frames.loc[frames["frame"] < end, "through_wall"].sum()),
        "frames_over_overlap_limit": int((overlaps > max_overlap).sum()),
        "max_overlap": float(overlaps.max()) if len(overlaps) else np.nan,
        f"p{OVERLAP_QUANTILE}_overlap_last": float(frames[f"p{OVERLAP_QUANTILE}_overlap"].iloc[-1]) if len(frames)
        else np.nan,
        "data_max_overlap": float(max(overlap_fractions(x, np.asarray(sim.traj.radius, float), sim.kinematic.numpy())
                                      .max(initial=0.0) for x in np.asarray(sim.traj.position, float))),
        "data_peak_kinetic_energy": peak,
        "final_kinetic_energy": float(frames["kinetic_energy"].iloc[-1]) if len(frames) else np.nan,
        "frames_outside_envelope": int(len(leaving)),
        "first_frame_outside_envelope": int(leaving["frame"].iloc[0]) if len(leaving) else np.nan,
        "envelope_cause": str(leaving["envelope_cause"].iloc[0]) if len(leaving) else "",
        "mse_recorded": float(mse.mean()) if len(mse) else np.nan, "mse_growth_per_step": error_growth(mse),
        "final_max_speed": float(np.max(speed)) if speed.size else np.nan, "wall_seconds": result.seconds,
    }
    return row, frames


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
                     noise_std: float, seed: int, max_overlap: float,
                     energy_envelope: float = float("inf")) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The report rows (long rollouts, precisions) and the long rollouts' per-frame table."""
    prepared = rt.apply(copy.deepcopy(simulator), runtime)
    rows, frames = [], []
    for s, sim in enumerate(sims):
        for length in lengths:
            row, table = long_rollout(prepared, runtime, sim, int(length), noise_std, seed + s, max_overlap,
                                      energy_envelope)
            rows.append(row)
            frames.append(table)
        rows.extend(precision_rows(simulator, runtime, sim))
    return pd.DataFrame(rows), pd.concat(frames, ignore_index=True)
