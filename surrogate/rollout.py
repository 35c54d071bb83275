"""Rollout (article 5.4.4): from the first K frames of a sim, predict every later frame in turn.

Kinematic particles are never predicted: at every step their positions are taken from the data.
A rollout that produces a non-finite position stops there; the remaining frames are NaN and the
first bad frame is reported, never hidden.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
import torch

from generators import h5md
from surrogate.samples import Sim
from surrogate.simulator import LearnedSimulator, build_graph


@dataclass
class Rollout:
    position: np.ndarray                 # [T, N, D]; frames < K are the data's
    history: int
    first_nonfinite: int | None = None   # first frame with a non-finite position, None if clean
    seconds: float = 0.0                 # wall time of the predicted frames
    seconds_graph: float = 0.0           # of which building the radius graph
    timing: dict = field(default_factory=dict)

    @property
    def n_predicted(self) -> int:
        """Frames the model computed (up to and including a first non-finite one)."""
        end = self.position.shape[0] if self.first_nonfinite is None else self.first_nonfinite + 1
        return end - self.history


@torch.inference_mode()
def rollout(simulator: LearnedSimulator, sim: Sim, n_frames: int | None = None) -> Rollout:
    """Predict frames ``K .. n_frames-1`` (default: as many frames as the sim has)."""
    k = simulator.history
    total = sim.n_frames if n_frames is None else int(n_frames)
    if sim.n_frames < k + 1 or total < k + 1:
        raise ValueError(f"{sim.path}: a rollout needs more than K = {k} frames, the sim has {sim.n_frames}")
    positions = torch.full((total, *sim.position.shape[1:]), float("nan"))
    positions[:k] = sim.position[:k]
    first_bad = None
    t_graph = 0.0
    start = time.perf_counter()
    for t in range(k, total):
        window = positions[t - k:t]
        t0 = time.perf_counter()
        graph = build_graph(window, sim.types, sim.kinematic, simulator.radius, sim.props)
        t_graph += time.perf_counter() - t0
        # beyond the recorded window, kinematic particles stay where the data left them
        kinematic_next = sim.position[min(t, sim.n_frames - 1)]
        nxt = simulator.step(graph, kinematic_next)
        if not torch.isfinite(nxt).all():
            first_bad = t
            break
        positions[t] = nxt
    seconds = time.perf_counter() - start
    return Rollout(positions.numpy(), k, first_bad, seconds, t_graph)


def rollout_mse(predicted: np.ndarray, truth: np.ndarray, moving: np.ndarray, history: int) -> np.ndarray:
    """Per predicted frame: mean over moving particles of the squared Euclidean error (docs/surrogate.md)."""
    err = np.asarray(predicted, np.float64)[history:, moving] - np.asarray(truth, np.float64)[history:, moving]
    return (err**2).sum(axis=-1).mean(axis=-1)


def write(path, sim: Sim, result: Rollout, checkpoint_path, checkpoint_sha: str):
    """The predicted trajectory as H5MD, same layout as the sim, with the rollout's provenance."""
    params = dict(sim.traj.parameters)
    params.update(source_sim=str(sim.path), rollout_checkpoint=str(checkpoint_path),
                  rollout_checkpoint_sha=checkpoint_sha, rollout_history=result.history,
                  rollout_first_nonfinite=-1 if result.first_nonfinite is None else result.first_nonfinite,
                  rollout_wall_time=result.seconds, rollout_graph_time=result.seconds_graph,
                  rollout_seconds_per_frame=result.seconds / max(result.n_predicted, 1),
                  content="Graph-DEM rollout: frames < rollout_history are the data's, later frames predicted")
    traj = replace(sim.traj, position=result.position.astype(np.float32), parameters=params, observables={})
    return h5md.write(path, traj, allow_nonfinite=True)
