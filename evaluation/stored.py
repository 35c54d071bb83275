"""Reading what the rollout and ensemble stages stored: a surrogate's rollout of a sim (checked against the
checkpoint and the history it is scored with) and the DEM ensemble's rerun of a sim (checked against the sim's
frames and particles). File readers only: they import neither torch nor the model, so the tests that score stored
files (the property-sensitivity test, the shear-stress check) start fast.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from generators import h5md

__all__ = ["read_ensemble", "read_rollout"]


def read_rollout(path: Path, sha: str, history: int) -> h5md.Trajectory:
    """The stored rollout of a sim (non-finite frames kept: a blown-up rollout is scored, not dropped); refused
    when another checkpoint made it (``sha``, :func:`surrogate.provenance.digest`) or it was given other than
    ``history`` frames."""
    traj = h5md.read(path, allow_nonfinite=True)
    made_by = traj.parameters.get("rollout_checkpoint_sha")
    if made_by != sha:
        raise ValueError(f"{path}: this rollout was made by checkpoint {made_by}, not by {sha}; rerun the rollout")
    given = traj.parameters.get("rollout_history")
    if given is not None and int(given) != int(history):
        raise ValueError(f"{path}: this rollout was given {given} frames, the evaluation {history}; "
                         f"evaluate with --history {given} or rerun the rollout")
    return traj


def read_ensemble(path: Path, traj: h5md.Trajectory, history: int | None = None) -> np.ndarray:
    """A DEM ensemble member of a sim: the same sweep row rerun by its engine and perturbed at the last given
    frame, on the same frames. With ``history`` (K), its first K frames must be the sim's own, bit for bit (the
    member starts where the surrogate starts)."""
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no DEM ensemble run of this sim (the ensemble stage makes one per test sim "
                                "and member)")
    member = h5md.read(path)
    if member.position.shape != traj.position.shape:
        raise ValueError(f"{path}: shape {member.position.shape} differs from the sim's {traj.position.shape}")
    if not np.allclose(member.time, traj.time, rtol=1e-9, atol=0.0):
        raise ValueError(f"{path}: its frames are recorded at other times than the sim's")
    if not np.array_equal(member.kinematic, traj.kinematic) or not np.array_equal(member.species, traj.species):
        raise ValueError(f"{path}: its particles (species or kinematic mask) differ from the sim's")
    position = np.asarray(member.position, np.float64)
    given = np.asarray(traj.position, np.float64)[:history]
    if history is not None and not np.array_equal(position[:history], given):
        worst = float(np.max(np.abs(position[:history] - given)))
        raise ValueError(f"{path}: its first {history} frames differ from the sim's (largest difference {worst:.3g} "
                         "m); a member must start from the sim's state at its last given frame (rerun the ensemble)")
    return position
