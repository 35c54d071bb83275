import copy
import json

import numpy as np
import pytest
import torch

from evaluation.baseline import constant_velocity
from generators import h5md
from surrogate import rollout, runtime
from surrogate.graph import build_graph
from surrogate.samples import load_sim
from surrogate.simulator import LearnedSimulator

pytestmark = pytest.mark.engine


def simulator_and_sim(tiny, split="test"):
    stats = json.loads(tiny["stats_json"])
    table = tiny["split_table"]
    torch.manual_seed(0)
    path = table.loc[table["split"] == split, "path"].iloc[0]
    return LearnedSimulator(stats, tiny["model"]).eval(), load_sim(path, stats)


def test_rollout_keeps_kinematic_particles_exactly_on_the_data(tiny_dataset):
    simulator, sim = simulator_and_sim(tiny_dataset)
    result = rollout.rollout(simulator, sim)
    kin = sim.kinematic.numpy()
    assert result.first_nonfinite is None and result.n_predicted == sim.n_frames - 4
    np.testing.assert_array_equal(result.position[:, kin], sim.position.numpy()[:, kin])
    np.testing.assert_array_equal(result.position[:4], sim.position.numpy()[:4])      # history is the data's
    assert not np.allclose(result.position[4:, ~kin], sim.position.numpy()[4:, ~kin])   # the rest is predicted


def test_rollout_given_more_frames_than_the_model_reads_starts_after_them(tiny_dataset):
    """G = K + 2 frames given: they are the data's, and frame G is predicted from frames G-K .. G-1."""
    simulator, sim = simulator_and_sim(tiny_dataset)
    k = simulator.history
    result = rollout.rollout(simulator, sim, given=k + 2)
    data = sim.position.numpy()
    assert result.history == k + 2 and result.n_predicted == sim.n_frames - k - 2
    np.testing.assert_array_equal(result.position[:k + 2], data[:k + 2])
    forced = rollout.rollout(simulator, sim, forced=True)      # every frame from the data's window
    np.testing.assert_allclose(result.position[k + 2], forced.position[k + 2], rtol=0, atol=1e-5)
    assert not np.allclose(result.position[k + 2:, ~sim.kinematic.numpy()], data[k + 2:, ~sim.kinematic.numpy()])
    with pytest.raises(ValueError, match=f"the model reads K = {k} frames; a rollout given {k - 1} cannot start"):
        rollout.rollout(simulator, sim, given=k - 1)


def test_rollout_beyond_the_recorded_window_holds_kinematic_particles(tiny_dataset):
    simulator, sim = simulator_and_sim(tiny_dataset)
    result = rollout.rollout(simulator, sim, n_frames=sim.n_frames + 5)
    kin = sim.kinematic.numpy()
    assert result.position.shape[0] == sim.n_frames + 5
    np.testing.assert_array_equal(result.position[-1, kin], sim.position.numpy()[-1, kin])


def test_blown_up_rollout_is_reported_and_written_as_nan(tiny_dataset, tmp_path):
    simulator, sim = simulator_and_sim(tiny_dataset)
    with torch.no_grad():
        simulator.acceleration_std.fill_(float("inf"))
    result = rollout.rollout(simulator, sim)
    assert result.first_nonfinite == 4 and np.isnan(result.position[4:]).all()
    path = rollout.write(tmp_path / "r.h5", sim, result, "ckpt.pt", "abc")
    back = h5md.read(path, allow_nonfinite=True)
    assert back.parameters["rollout_first_nonfinite"] == 4
    with pytest.raises(h5md.H5MDError, match="non-finite position at frame 4"):
        h5md.read(path)


def test_rollout_file_has_the_sims_layout(tiny_dataset, tmp_path):
    simulator, sim = simulator_and_sim(tiny_dataset)
    path = rollout.write(tmp_path / "r.h5", sim, rollout.rollout(simulator, sim), "ckpt.pt", "abc")
    back = h5md.read(path)
    assert back.position.shape == sim.traj.position.shape
    np.testing.assert_array_equal(back.species, sim.traj.species)
    np.testing.assert_array_equal(back.time, sim.traj.time)
    assert back.parameters["rollout_checkpoint_sha"] == "abc" and back.parameters["scene"] == "slide"


def test_constant_velocity_is_exact_for_uniform_motion():
    t = np.arange(8)[:, None, None]
    pos = np.array([[0.0, 0.0], [5.0, 1.0], [9.0, 9.0]])[None] + np.array([[1.0, 0.5], [-0.2, 0.0], [0, 0]]) * t
    kin = np.array([False, False, True])
    pos[:, 2] = [9.0, 9.0 + 0.0]
    pred = constant_velocity(pos, kin, history=3)
    np.testing.assert_allclose(pred, pos)
    accelerating = pos + np.array([0.0, -0.1])[None, None] * t**2
    accelerating[:, 2] = pos[:, 2]
    pred = constant_velocity(accelerating, kin, history=3)
    assert np.allclose(pred[:3], accelerating[:3]) and not np.allclose(pred[3:, :2], accelerating[3:, :2])
    np.testing.assert_array_equal(pred[:, 2], accelerating[:, 2])


def test_rollout_mse_is_mean_squared_euclidean_over_moving_particles():
    truth = np.zeros((4, 3, 2))
    pred = truth.copy()
    pred[2:, 0] = [3.0, 4.0]               # 25 m^2 on particle 0
    pred[2:, 2] = [100.0, 0.0]             # kinematic: not counted
    mse = rollout.rollout_mse(pred, truth, np.array([True, True, False]), history=2)
    np.testing.assert_allclose(mse, [12.5, 12.5])


def test_forced_rollout_predicts_every_frame_from_the_datas_window(untrained):
    simulator, sim = untrained
    with torch.no_grad():                          # zero acceleration: next = 2 x_t - x_{t-1}
        simulator.acceleration_std.zero_()
        simulator.acceleration_mean.zero_()
    result = rollout.rollout(simulator, sim, forced=True)
    data = sim.position.numpy()
    np.testing.assert_allclose(result.position[4:], 2 * data[3:-1] - data[2:-2], atol=1e-4)
    with pytest.raises(ValueError, match="a forced rollout needs the data's frames"):
        rollout.rollout(simulator, sim, n_frames=sim.n_frames + 1, forced=True)


def test_a_bundled_rollout_predicts_b_frames_per_call_from_the_last_window(tiny_dataset):
    """A model of bundle 4 over the 6 predicted frames: two calls. Frames K .. K+3 are the first call's, from the
    data's window; frames K+4 and K+5 the first two of the second call's, from the four frames predicted before;
    the kinematic particles stay on the data, and the runtime's path (the evaluate stage's) predicts the same."""
    stats = json.loads(tiny_dataset["stats_json"])
    table = tiny_dataset["split_table"]
    torch.manual_seed(0)
    simulator = LearnedSimulator(stats, {**tiny_dataset["model"], "bundle": 4}).eval()
    sim = load_sim(table.loc[table["split"] == "test", "path"].iloc[0], stats)
    k, n = simulator.history, sim.n_frames
    assert (k, n) == (4, 10)
    result = rollout.rollout(simulator, sim)
    with torch.no_grad():
        first = simulator.step(build_graph(sim.position[:k], sim.types, sim.kinematic, simulator.radius),
                               sim.position[k:k + 4])
        later = torch.stack([sim.position[min(t, n - 1)] for t in range(k + 4, k + 8)])
        second = simulator.step(build_graph(first, sim.types, sim.kinematic, simulator.radius), later)
    assert result.first_nonfinite is None and result.n_predicted == n - k
    np.testing.assert_array_equal(result.position[k:k + 4], first.numpy())
    np.testing.assert_array_equal(result.position[k + 4:], second[:2].numpy())
    kin = sim.kinematic.numpy()
    np.testing.assert_array_equal(result.position[:, kin], sim.position.numpy()[:, kin])
    # counts are per network call: two calls of every particle's node (per frame it would be a third of that)
    assert result.timing["nodes_per_step"] == sim.kinematic.numel()
    rt = runtime.Runtime(split_edge_mlp=True, skip_kinematic_pairs=True, prune_isolated=True, precision="float32",
                         sleep_speed=None, keep_in_domain=False, compile=False)
    prepared = runtime.apply(copy.deepcopy(simulator), rt)
    configured = rollout.rollout(prepared, sim, runtime=rt)
    moved = np.abs(result.position[-1] - result.position[k - 1]).max()
    np.testing.assert_allclose(configured.position, result.position, rtol=1e-5, atol=1e-5 * moved)
