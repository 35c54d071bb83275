"""A trained surrogate from Python: load a checkpoint, roll it out on a trajectory, score the rollout.

Everything here works on :class:`generators.h5md.Trajectory`, the in-memory form of one H5MD file, so a
rollout can be written with :func:`generators.h5md.write` and read by every tool that reads the sims.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from generators import h5md
from surrogate import checkpoint, samples
from surrogate import rollout as rollouts
from surrogate.simulator import LearnedSimulator


def load_simulator(path: str | Path, device: str = "cpu") -> LearnedSimulator:
    """The trained simulator of a ``best.pt`` or ``last.pt``, in eval mode, on ``device`` (``auto``, ``cpu``,
    ``cuda`` or ``cuda:N``; a rollout runs there); ``.stats`` and ``.model_config`` hold the dataset statistics
    and model config it was trained with."""
    return checkpoint.simulator_from(path, device)[0]


def _trajectory(sim: h5md.Trajectory | str | Path) -> tuple[h5md.Trajectory, Path]:
    if isinstance(sim, h5md.Trajectory):
        return sim, Path("<trajectory>")       # in memory: named so in messages
    return h5md.read(sim), Path(sim)


def rollout(simulator: LearnedSimulator, sim: h5md.Trajectory | str | Path, steps: int | None = None,
            allow_other_scene: bool = False) -> h5md.Trajectory:
    """Predict ``steps`` frames after the first K of ``sim`` (default: through the sim's last frame).

    The result has K + ``steps`` frames: the first K are the sim's, the rest predicted; kinematic particles
    follow the sim (and stay at its last frame beyond it, with frame times continued at the last interval).
    A rollout that leaves the finite numbers keeps NaN from there on (``rollout_first_nonfinite``).
    """
    traj, path = _trajectory(sim)
    k = simulator.history
    steps = traj.n_frames - k if steps is None else int(steps)
    if steps < 1:
        raise ValueError(f"{path}: a rollout predicts at least one frame; the sim has {traj.n_frames} frames "
                         f"and the model reads K = {k}")
    loaded = samples.load_sim(path, simulator.stats, simulator.property_names, traj=traj,
                              allow_other_scene=allow_other_scene)
    result = rollouts.rollout(simulator, loaded, k + steps)
    total = k + steps
    extra = max(total - traj.n_frames, 0)
    interval = traj.time[-1] - traj.time[-2]
    stride = traj.step[-1] - traj.step[-2]
    time = np.concatenate([traj.time[:total], traj.time[-1] + interval * np.arange(1, extra + 1)])
    step = np.concatenate([traj.step[:total], traj.step[-1] + stride * np.arange(1, extra + 1)])
    parameters = {**traj.parameters, "rollout_history": k,
                  "rollout_first_nonfinite": -1 if result.first_nonfinite is None else result.first_nonfinite,
                  "rollout_wall_time": result.seconds}
    return replace(traj, position=result.position.astype(np.float32), time=time, step=step.astype(traj.step.dtype),
                   parameters=parameters, observables={})


def rollout_mse(prediction: h5md.Trajectory, truth: h5md.Trajectory) -> float:
    """Rollout MSE (m²): the squared position error of the moving particles, averaged over particles and over
    the predicted frames both trajectories hold (the evaluate stage's definition, docs/surrogate.md)."""
    history = int(prediction.parameters.get("rollout_history", 0))
    if history < 1:
        raise ValueError("the prediction carries no rollout_history: pass the trajectory rollout() returned")
    if prediction.n_particles != truth.n_particles:
        raise ValueError(f"the prediction has {prediction.n_particles} particles, the truth {truth.n_particles}")
    frames = min(prediction.n_frames, truth.n_frames)
    if frames <= history:
        raise ValueError(f"no predicted frame to score: {frames} common frames, {history} given")
    moving = ~np.asarray(truth.kinematic, bool)
    per_frame = rollouts.rollout_mse(prediction.position[:frames], truth.position[:frames], moving, history)
    return float(per_frame.mean())
