"""A trained surrogate from Python: load a checkpoint, roll it out on a trajectory, score the rollout.

Everything here works on :class:`generators.h5md.Trajectory`, the in-memory form of one H5MD file, so a
rollout can be written with :func:`generators.h5md.write` and read by every tool that reads the sims.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from generators import h5md
from surrogate import checkpoint as checkpoint_module
from surrogate import rollout as rollouts
from surrogate import samples
from surrogate.simulator import LearnedSimulator


def load_simulator(checkpoint: str | Path, device: str = "auto", threads: int | None = 1) -> LearnedSimulator:
    """The trained simulator of a checkpoint (a ``best.pt`` or ``last.pt``) or of a pretrained model named by its
    scene (``"slide"``: :mod:`surrogate.pretrained`), in eval mode, on ``device`` (``auto``: the first CUDA GPU
    torch sees, else the CPU; ``cpu``, ``cuda``, ``cuda:N``); a rollout runs there.

    ``threads`` sets torch's CPU threads for the process, as every ``graphdem`` command does (1: a rollout of a few
    hundred particles is fastest on one thread, and a loaded machine's cores are not oversubscribed); None leaves
    torch's setting. ``.stats`` and ``.model_config`` hold the dataset statistics and model config it was trained
    with; ``.runtime`` the runtime switches a rollout uses by default: a pretrained model's, those its test
    metrics were measured with (compiling left off: it changes the speed, not the result), else None (the
    computation as in training).
    """
    import torch

    from surrogate import pretrained
    from surrogate import runtime as runtimes
    if threads is not None:
        if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
            raise ValueError(f"threads = {threads!r}: a number of CPU threads >= 1, or None (torch's setting)")
        torch.set_num_threads(threads)
    path = Path(checkpoint)
    if not path.exists() and pretrained.is_name(checkpoint):
        path = pretrained.path(str(checkpoint))
    simulator, meta = checkpoint_module.simulator_from(path, device)
    published = (meta.get("pretrained") or {}).get("runtime")
    simulator.runtime = None
    if published is not None:
        simulator.runtime = runtimes.Runtime.from_config({**published, "compile": False})
        simulator = runtimes.apply(simulator, simulator.runtime)
    return simulator


def _trajectory(sim: h5md.Trajectory | str | Path) -> tuple[h5md.Trajectory, Path]:
    if isinstance(sim, h5md.Trajectory):
        return sim, Path("<trajectory>")       # in memory: named so in messages
    return h5md.read(sim), Path(sim)


def rollout(simulator: LearnedSimulator, sim: h5md.Trajectory | str | Path, steps: int | None = None,
            allow_other_scene: bool = False, runtime: dict | None = None) -> h5md.Trajectory:
    """Predict ``steps`` frames after the first K of ``sim`` (default: through the sim's last frame).

    The result has K + ``steps`` frames: the first K are the sim's, the rest predicted; kinematic particles
    follow the sim (and stay at its last frame beyond it, with frame times continued at the last interval).
    A rollout that leaves the finite numbers keeps NaN from there on (``rollout_first_nonfinite``).
    ``runtime``: the runtime switches (a scene config's ``runtime`` section, docs/surrogate.md), applied to
    ``simulator`` and kept as its ``.runtime``; None: the simulator's own (:func:`load_simulator`).
    """
    from surrogate import runtime as runtimes
    if runtime is not None:
        simulator.runtime = runtimes.Runtime.from_config(runtime)
        simulator = runtimes.apply(simulator, simulator.runtime)
    traj, path = _trajectory(sim)
    k = simulator.history
    steps = traj.n_frames - k if steps is None else int(steps)
    if steps < 1:
        raise ValueError(f"{path}: a rollout predicts at least one frame; the sim has {traj.n_frames} frames "
                         f"and the model reads K = {k}")
    loaded = samples.load_sim(path, simulator.stats, simulator.property_names, traj=traj,
                              allow_other_scene=allow_other_scene)
    result = rollouts.rollout(simulator, loaded, k + steps, runtime=getattr(simulator, "runtime", None))
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
