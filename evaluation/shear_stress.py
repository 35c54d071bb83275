"""The shear-stress readout: the shear stress of a direct shear test read from one frame's particles.

Graph-DEM predicts positions; the test's observable is a force: the x contact force the soil exerts on the
held part of the box (the upper frame and the platen, ``generators.scenes.shear``), over the shear area A.
The readout computes it the way the DEM does, as a sum of pair forces over the soil-wall pairs that touch
(or nearly touch, ``cutoff``), with the pair force learned from the DEM's own frames:

    tau / sigma_n = (1 / A) sum_{i soil, j held, gap_ij < cutoff} (r_i + r_j)^2 g_ij,
    g_ij = s_ij a_theta(e_ij) + b_theta(e_ij)

where sigma_n is the sim's normal stress and a_theta, b_theta the two outputs of an MLP of the pair's
dimensionless description e_ij:
the unit vector n_ij from i to j, the gap (|x_j - x_i| / (r_i + r_j) - 1), the stiffness-scaled overlap
s_ij = (E / sigma_n) max(-gap, 0) (a linear contact's normal force in units of sigma_n (r_i + r_j)^2, up to a
constant), the relative velocity over the last frame interval in units of r_i + r_j, log10(E / sigma_n) and
the held particle's species (one-hot). Each feature is standardised by its train-set mean and std, stored with
the weights. The pair force is linear in s_ij (a linear contact's normal force is s_ij / 2 along n_ij, so
a = n_x / 2, b = 0 is the frictionless linear spring), so that it grows with the overlap as the DEM's contact
law does, also beyond the overlaps of the training frames. Tangential forces depend on the contact's history,
which one frame does not hold: the relative velocity is what a and b see of it.

The held particles are the kinematic ones that do not move along the shear: those whose x changes over the
recorded window by less than half the largest change of a kinematic particle (the lower half moves the full
displacement, the upper frame and the platen not at all in x).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
import torch
from tqdm import tqdm

from surrogate import checkpoint, dataset

log = logging.getLogger("graphdem.stress")

# the per-pair features, in the order of PairSet.features (after the held species' one-hot)
FEATURES = ("n_x", "n_y", "n_z", "gap", "scaled_overlap", "dv_x", "dv_y", "dv_z", "log_stiffness_ratio")


def held_mask(position: np.ndarray, kinematic: np.ndarray) -> np.ndarray:
    """[N] bool: the kinematic particles held along the shear axis x (module docstring)."""
    kin = np.asarray(kinematic, bool)
    if not kin.any():
        raise ValueError("the sim has no kinematic particles: a shear readout needs the box's held walls")
    shift = np.abs(np.asarray(position, np.float64)[-1, :, 0] - np.asarray(position, np.float64)[0, :, 0])
    largest = shift[kin].max()
    if largest <= 0:
        raise ValueError("no kinematic particle moves in x over the window: no shear to read")
    return kin & (shift < 0.5 * largest)


@dataclass
class Sample:
    """One sim, what the readout needs from it: positions, radii, masks and its stress parameters."""

    id: str
    position: np.ndarray      # [T, N, 3] m
    radius: np.ndarray        # [N] m
    soil: np.ndarray          # [N] bool, the moving particles
    held: np.ndarray          # [N] bool
    species: np.ndarray       # [N] int
    normal_stress: float      # Pa, the set normal stress (sigma_n)
    young: float              # Pa, the soil's modulus (E)
    area: float               # m^2, the shear area A
    n_types: int
    shear_stress: np.ndarray  # [T] Pa, the DEM's observable (NaN where the file has none)

    @classmethod
    def from_trajectory(cls, traj, position: np.ndarray | None = None) -> Sample:
        """``traj``'s particles and parameters; its positions or ``position`` (a rollout of it, [T, N, 3])."""
        p = traj.parameters
        missing = [k for k in ("normal_stress", "young", "shear_area") if k not in p]
        if missing:
            raise ValueError(f"sim {p.get('id', '?')}: no {', '.join(missing)} parameter; the shear readout needs "
                             f"a direct shear sim under normal load (generators.scenes.shear)")
        pos = np.asarray(traj.position if position is None else position, np.float64)
        kinematic = np.asarray(traj.kinematic, bool)
        observed = traj.observables.get("shear_stress")
        return cls(str(p["id"]), pos, dataset.property_values(traj, "radius"), ~kinematic,
                   held_mask(np.asarray(traj.position), kinematic), np.asarray(traj.species, int),
                   float(p["normal_stress"]), float(p["young"]), float(p["shear_area"]),
                   int(np.asarray(traj.species).max()) + 1,
                   np.full(len(pos), np.nan) if observed is None else np.asarray(observed, np.float64))


@dataclass
class PairSet:
    """The soil-wall pairs of a sim's frames 1..T-1: raw features, weights (r_i + r_j)^2 / A, and frame index."""

    features: np.ndarray      # [P, n_types + len(FEATURES)]
    weight: np.ndarray        # [P]
    frame: np.ndarray         # [P] int, 0 .. T-2 for frames 1 .. T-1
    n_frames: int


def pairs(sample: Sample, cutoff: float, n_types: int) -> PairSet:
    """Every (soil, held) pair with gap < ``cutoff`` in frames 1..T-1 (the first frame has no velocity)."""
    pos, r = sample.position, sample.radius
    soil, held = np.flatnonzero(sample.soil), np.flatnonzero(sample.held)
    kappa = sample.young / sample.normal_stress
    reach = r[soil][:, None] + r[held][None, :]                       # [S, H]
    rows, weights, frames = [], [], []
    finite = np.isfinite(pos).all(axis=(1, 2))
    for t in range(1, len(pos)):
        if not (finite[t] and finite[t - 1]):          # a broken frame has no pairs (read gives it NaN)
            continue
        d = pos[t, held][None, :, :] - pos[t, soil][:, None, :]         # [S, H, 3], soil -> wall
        dist = np.linalg.norm(d, axis=-1)
        gap = dist / reach - 1.0
        i, j = np.nonzero(gap < cutoff)
        if not len(i):
            continue
        n = d[i, j] / dist[i, j, None]
        dv = ((pos[t, held[j]] - pos[t - 1, held[j]]) - (pos[t, soil[i]] - pos[t - 1, soil[i]])) / reach[i, j, None]
        onehot = np.eye(n_types)[sample.species[held[j]]]
        g = gap[i, j]
        rows.append(np.column_stack([onehot, n, g, kappa * np.maximum(-g, 0.0), dv,
                                     np.full(len(i), math.log10(kappa))]))
        weights.append(reach[i, j] ** 2 / sample.area)
        frames.append(np.full(len(i), t - 1))
    if not rows:
        return PairSet(np.zeros((0, n_types + len(FEATURES))), np.zeros(0), np.zeros(0, int), len(pos) - 1)
    return PairSet(np.concatenate(rows), np.concatenate(weights), np.concatenate(frames), len(pos) - 1)


class StressReadout(torch.nn.Module):
    """tau / sigma_n of a frame as the weighted sum of learned pair forces (module docstring's equation)."""

    def __init__(self, n_features: int, hidden: int, layers: int, mean: torch.Tensor, std: torch.Tensor):
        super().__init__()
        sizes = [n_features] + [hidden] * layers
        mods: list[torch.nn.Module] = []
        for a, b in zip(sizes[:-1], sizes[1:], strict=True):
            mods += [torch.nn.Linear(a, b), torch.nn.SiLU()]
        self.mlp = torch.nn.Sequential(*mods, torch.nn.Linear(sizes[-1], 2))
        self.overlap_column = n_features - len(FEATURES) + FEATURES.index("scaled_overlap")
        self.register_buffer("mean", mean.float())
        self.register_buffer("std", std.float())

    def forward(self, features: torch.Tensor, weight: torch.Tensor, frame: torch.Tensor, n_frames: int) -> torch.Tensor:
        """[n_frames] tau / sigma_n from the pairs' raw ``features`` [P, F], ``weight`` [P] and ``frame`` [P]."""
        a, b = self.mlp((features - self.mean) / self.std).unbind(-1)
        g = features[:, self.overlap_column] * a + b
        return torch.zeros(n_frames, dtype=g.dtype, device=g.device).index_add(0, frame, weight * g)


def standardisation(sets: list[PairSet]) -> tuple[torch.Tensor, torch.Tensor]:
    """Mean and std of every feature over the pairs of ``sets`` (std 1 where a feature is constant)."""
    x = np.concatenate([s.features for s in sets])
    if not len(x):
        raise ValueError("no soil-wall pair within the cutoff in any training frame: raise shear_stress_readout.cutoff")
    std = x.std(axis=0)
    return torch.tensor(x.mean(axis=0)), torch.tensor(np.where(std > 0, std, 1.0))


def read(model: StressReadout, sample: Sample, cutoff: float) -> np.ndarray:
    """[T] the shear stress (Pa) the readout gives for each frame of ``sample`` (frame 0: NaN, no velocity);
    NaN on a frame with a non-finite position."""
    n_types = model.mean.numel() - len(FEATURES)
    finite = np.isfinite(sample.position).all(axis=(1, 2))
    s = pairs(sample, cutoff, n_types)
    with torch.no_grad():
        ratio = model(torch.tensor(s.features, dtype=torch.float32), torch.tensor(s.weight, dtype=torch.float32),
                      torch.tensor(s.frame), s.n_frames).double().numpy()
    tau = np.concatenate([[np.nan], ratio * sample.normal_stress])
    tau[~finite | ~np.roll(finite, 1)] = np.nan
    return tau


def _stack(sets: list[PairSet]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, int]:
    """The pairs of several sims as one batch, their frames numbered one after another."""
    offsets = np.cumsum([0] + [s.n_frames for s in sets])
    frame = np.concatenate([s.frame + o for s, o in zip(sets, offsets, strict=False)])
    return (torch.tensor(np.concatenate([s.features for s in sets]), dtype=torch.float32),
            torch.tensor(np.concatenate([s.weight for s in sets]), dtype=torch.float32),
            torch.tensor(frame), int(offsets[-1]))


def _targets(samples: list[Sample]) -> torch.Tensor:
    """tau / sigma_n of frames 1..T-1 of every sample, one after another."""
    ratio = np.concatenate([s.shear_stress[1:] / s.normal_stress for s in samples])
    if not np.isfinite(ratio).all():
        bad = [s.id for s in samples if not np.isfinite(s.shear_stress[1:]).all()]
        raise ValueError(f"sims {', '.join(bad)}: no finite shear_stress observable in every frame; the readout "
                         f"learns from the DEM's (written by the shear scene since its load platen)")
    return torch.tensor(ratio, dtype=torch.float32)


def fit(train: list[Sample], valid: list[Sample], cfg: dict, progress: bool = True,
        threads: int = 1) -> tuple[StressReadout, dict, pd.DataFrame]:
    """Train the readout on the ``train`` sims' frames (full batch, Adam, on ``threads`` CPU threads), keep the epoch
    with the lowest valid MSE of tau / sigma_n. ``cfg``: the scene's ``shear_stress_readout`` (cutoff, hidden, layers,
    epochs, lr, seed). Returns the model, its metadata (for :func:`save`) and the history (epoch, train and valid
    MSE)."""
    torch.set_num_threads(int(threads))
    if not train or not valid:
        raise ValueError(f"the shear readout needs train and valid sims, got {len(train)} and {len(valid)}")
    cutoff, n_types = float(cfg["cutoff"]), max(s.n_types for s in train + valid)
    train_sets = [pairs(s, cutoff, n_types) for s in train]
    valid_sets = [pairs(s, cutoff, n_types) for s in valid]
    mean, std = standardisation(train_sets)
    torch.manual_seed(int(cfg["seed"]))
    model = StressReadout(mean.numel(), int(cfg["hidden"]), int(cfg["layers"]), mean, std)
    optimiser = torch.optim.Adam(model.parameters(), lr=float(cfg["lr"]))
    xt, wt, ft, nt = _stack(train_sets)
    xv, wv, fv, nv = _stack(valid_sets)
    yt, yv = _targets(train), _targets(valid)
    best, best_state, rows = math.inf, None, []
    for epoch in tqdm(range(int(cfg["epochs"])), desc="stress readout", disable=not progress, mininterval=2.0):
        loss = torch.mean((model(xt, wt, ft, nt) - yt) ** 2)
        optimiser.zero_grad(set_to_none=True)
        loss.backward()
        optimiser.step()
        with torch.no_grad():
            valid_mse = float(torch.mean((model(xv, wv, fv, nv) - yv) ** 2))
        rows.append({"epoch": epoch + 1, "train_mse": loss.item(), "valid_mse": valid_mse})
        if valid_mse < best:
            best, best_state = valid_mse, {k: v.detach().clone() for k, v in model.state_dict().items()}
    model.load_state_dict(best_state)
    history = pd.DataFrame(rows)
    meta = {"cutoff": cutoff, "hidden": int(cfg["hidden"]), "layers": int(cfg["layers"]), "n_types": n_types,
            "features": list(FEATURES), "epoch": int(history["valid_mse"].idxmin()) + 1, "valid_mse": best,
            "train_sims": [s.id for s in train], "valid_sims": [s.id for s in valid],
            "train_stress_ratio": [(s.shear_stress / s.normal_stress).tolist() for s in train]}
    log.info("stress readout: best valid MSE of tau / sigma_n %.4g at epoch %d of %d", best, meta["epoch"],
             len(history))
    return model.eval(), meta, history


def save(path, model: StressReadout, meta: dict) -> None:
    """Weights and metadata, as every checkpoint: tensors and JSON only (surrogate.checkpoint)."""
    checkpoint.save(path, {"model": model.state_dict(), "json": meta})


def load(path) -> tuple[StressReadout, dict]:
    saved = checkpoint.read(path)
    meta = saved["json"]
    if not isinstance(meta, dict) or "cutoff" not in meta or "features" not in meta:
        raise ValueError(f"{path}: not a shear-stress readout (no cutoff or features in its metadata)")
    if list(meta["features"]) != list(FEATURES):
        raise ValueError(f"{path}: made with features {meta['features']}, this version reads {list(FEATURES)}: "
                         f"retrain the readout")
    state = saved["model"]
    try:
        model = StressReadout(state["mean"].numel(), int(meta["hidden"]), int(meta["layers"]), state["mean"],
                              state["std"])
        model.load_state_dict(state)
    except (KeyError, RuntimeError, TypeError, AttributeError) as exc:
        raise checkpoint.CheckpointError(f"{path}: weights do not fit the readout it describes: {exc}") from exc
    return model.eval(), meta
