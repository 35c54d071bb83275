import numpy as np
import pytest

from evaluation.baseline import constant_velocity
from surrogate.runtime import Runtime


def runtime(keep_in_domain: bool, contact_correction: dict | None = None) -> Runtime:
    return Runtime(split_edge_mlp=True, skip_kinematic_pairs=True, prune_isolated=True, precision="float32",
                   sleep_speed=None, keep_in_domain=keep_in_domain, compile=False,
                   contact_correction=contact_correction)


def moving_to_the_wall() -> np.ndarray:
    """[8, 2, 2]: particle 0 moves at +1 m per frame in x towards the face x = 5 (from x = 0), particle 1 rests."""
    t = np.arange(8, dtype=float)
    pos = np.zeros((8, 2, 2))
    pos[:, 0, 0] = t
    pos[:, 1] = [2.0, 2.0]
    return pos


BOX = (np.array([-1.0, -1.0]), np.array([5.0, 5.0]))


def test_with_the_models_box_clamp_the_baseline_stops_on_the_face_instead_of_leaving_the_box():
    pos = moving_to_the_wall()
    kinematic = np.array([False, False])
    free = constant_velocity(pos, kinematic, history=3)
    np.testing.assert_allclose(free[:, 0, 0], np.arange(8))                   # 7 m: 2 m outside the box
    clamped = constant_velocity(pos, kinematic, 3, runtime(True), BOX, np.array([0.1, 0.1]))
    np.testing.assert_allclose(clamped[:, 0, 0], [0, 1, 2, 3, 4, 5, 5, 5])    # stops at x = 5 and stays there
    np.testing.assert_allclose(clamped[:, 1], pos[:, 1])


def test_a_runtime_without_clamp_or_correction_gives_the_plain_extrapolation():
    pos = moving_to_the_wall()
    kinematic = np.array([False, True])
    np.testing.assert_array_equal(constant_velocity(pos, kinematic, 3, runtime(False)),
                                  constant_velocity(pos, kinematic, 3))


def test_the_contact_correction_pushes_the_baselines_overlaps_apart_as_the_models():
    pos = np.zeros((5, 2, 2))
    pos[:, 0, 0] = [0.0, 0.1, 0.2, 0.3, 0.4]                                 # walks into a resting neighbour
    pos[:, 1, 0] = 0.6
    kinematic = np.array([False, False])
    radius = np.array([0.25, 0.25])
    free = constant_velocity(pos, kinematic, 2)
    corrected = constant_velocity(pos, kinematic, 2, runtime(False, {"allowed_overlap": 0.05, "iterations": 50}),
                                  BOX, radius)
    gap = np.abs(corrected[-1, 1, 0] - corrected[-1, 0, 0])
    assert np.abs(free[-1, 1, 0] - free[-1, 0, 0]) < 0.5 - 0.05 * 0.25            # the plain one overlaps deeper
    assert gap >= 0.5 - 0.05 * 0.25 - 1e-9


def test_a_clamp_without_the_box_is_refused_by_name():
    with pytest.raises(ValueError, match="needs the data's box"):
        constant_velocity(moving_to_the_wall(), np.array([False, False]), 3, runtime(True))


def test_the_extrapolation_of_a_checkpoint_runs_under_its_runtime_and_its_models_box(saved_checkpoint):
    """`Extrapolation.of`: the runtime of the scene's section and the box of the checkpoint's model, the same
    constant velocity `graphdem evaluate` scores; without a runtime, the plain extrapolation."""
    from evaluation.baseline import Extrapolation
    from generators import h5md
    from surrogate import checkpoint
    path, sim, _ = saved_checkpoint
    traj = h5md.read(sim)
    simulator, _ = checkpoint.simulator_from(path)
    box = (simulator.lower.double().numpy(), simulator.upper.double().numpy())
    section = {"split_edge_mlp": True, "skip_kinematic_pairs": True, "prune_isolated": True, "precision": "float32",
               "sleep_speed": None, "keep_in_domain": True, "compile": False,
               "contact_correction": {"allowed_overlap": 0.05, "iterations": 20}}
    extrapolate = Extrapolation.of(path, section)
    np.testing.assert_array_equal(extrapolate.box[0], box[0])
    np.testing.assert_array_equal(extrapolate.box[1], box[1])
    want = constant_velocity(traj.position, traj.kinematic, 4, Runtime.from_config(section), box, traj.radius)
    np.testing.assert_array_equal(extrapolate(traj, 4), want)
    np.testing.assert_array_equal(Extrapolation.of(path, None)(traj, 4),
                                  constant_velocity(traj.position, traj.kinematic, 4))
    assert not np.array_equal(want, constant_velocity(traj.position, traj.kinematic, 4))   # the runtime acts here
