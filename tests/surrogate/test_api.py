"""The Python API: a checkpoint loaded, rolled out on a trajectory (in memory or a file), and scored."""


import numpy as np
import pytest

from generators import h5md
from surrogate import api
from surrogate import rollout as rollouts
from surrogate.samples import load_sim

pytestmark = pytest.mark.engine


@pytest.fixture
def saved(saved_checkpoint):
    """An initialised (seed 0) simulator saved as a checkpoint, and the path of the first test sim."""
    return saved_checkpoint[:2]


def test_a_checkpoint_rolls_out_as_the_rollout_stage_does(saved):
    path, sim_path = saved
    simulator = api.load_simulator(path)
    assert simulator.history == 4 and simulator.stats["dim"] == 2 and not simulator.training
    sim = h5md.read(sim_path)
    predicted = api.rollout(simulator, sim)
    stage = rollouts.rollout(simulator, load_sim(sim_path, simulator.stats))
    np.testing.assert_array_equal(predicted.position, stage.position.astype(np.float32))
    np.testing.assert_array_equal(predicted.position[:4], sim.position[:4])         # the K frames given
    np.testing.assert_array_equal(predicted.time, sim.time)
    assert predicted.parameters["rollout_history"] == 4 and predicted.parameters["rollout_first_nonfinite"] == -1
    np.testing.assert_array_equal(api.rollout(simulator, sim_path).position, predicted.position)   # from a file


def test_rollout_mse_is_the_mean_squared_distance_of_the_moving_particles(saved):
    path, sim_path = saved
    simulator, sim = api.load_simulator(path), h5md.read(sim_path)
    predicted = api.rollout(simulator, sim)
    moving = ~sim.kinematic
    by_hand = ((predicted.position[4:, moving].astype(float) - sim.position[4:, moving]) ** 2).sum(-1).mean()
    assert api.rollout_mse(predicted, sim) == pytest.approx(by_hand, rel=1e-9) and by_hand > 0
    assert api.rollout_mse(h5md.Trajectory(**{**vars(sim), "parameters": {"rollout_history": 4}}), sim) == 0.0
    with pytest.raises(ValueError, match="carries no rollout_history"):
        api.rollout_mse(sim, sim)


def test_a_rollout_beyond_the_data_continues_the_frame_times(saved):
    path, sim_path = saved
    simulator, sim = api.load_simulator(path), h5md.read(sim_path)
    predicted = api.rollout(simulator, sim, steps=sim.n_frames)          # K + T frames: K beyond the data
    assert predicted.n_frames == sim.n_frames + 4
    interval = sim.time[-1] - sim.time[-2]
    np.testing.assert_allclose(np.diff(predicted.time[sim.n_frames - 1:]), interval, rtol=1e-9)
    np.testing.assert_array_equal(predicted.position[-1, sim.kinematic], sim.position[-1, sim.kinematic])
    predicted.validate("rollout")                                        # a valid trajectory, writable as H5MD
    assert api.rollout_mse(predicted, sim) > 0                           # scored on the frames both hold
    with pytest.raises(ValueError, match="predicts at least one frame"):
        api.rollout(simulator, sim, steps=0)


def test_the_api_defaults_to_one_thread_and_the_auto_device_as_the_commands_do(saved):
    import torch
    path, _ = saved
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        simulator = api.load_simulator(path)
        assert torch.get_num_threads() == 1 and simulator.runtime is None      # a plain checkpoint: as in training
        expected = "cuda" if torch.cuda.is_available() else "cpu"
        assert next(simulator.parameters()).device.type == expected
        torch.set_num_threads(2)
        api.load_simulator(path, device="cpu", threads=None)                   # None leaves torch's setting
        assert torch.get_num_threads() == 2
        with pytest.raises(ValueError, match="threads = 0: a number of CPU threads >= 1"):
            api.load_simulator(path, threads=0)
    finally:
        torch.set_num_threads(before)


def test_a_pretrained_model_loads_by_name_with_its_runtime(saved, tmp_path, monkeypatch):
    from surrogate import checkpoint, pretrained
    path, sim_path = saved
    runtime = {"split_edge_mlp": True, "skip_kinematic_pairs": True, "prune_isolated": True, "precision": "float32",
               "sleep_speed": None, "keep_in_domain": True, "compile": True,
               "contact_correction": {"allowed_overlap": 0.05, "iterations": 50}}
    stored = checkpoint.load(path)
    (tmp_path / "shipped").mkdir()
    checkpoint.save(tmp_path / "shipped" / "slide.pt", {"model": stored["model"],
                                                        "json": {**stored["json"], "pretrained": {"runtime": runtime}}})
    monkeypatch.setattr(pretrained, "FOLDER", tmp_path / "shipped")
    assert pretrained.names() == ["slide"]
    simulator = api.load_simulator("slide", device="cpu")
    assert simulator.runtime.as_dict() == {**runtime, "compile": False}       # compiling changes only the speed
    sim = h5md.read(sim_path)
    corrected = api.rollout(simulator, sim)
    plain = api.rollout(api.load_simulator(path, device="cpu"), sim)
    assert not np.array_equal(corrected.position, plain.position)            # the contact correction is applied
    switched = api.rollout(simulator, sim, runtime={**runtime, "contact_correction": None, "compile": False})
    np.testing.assert_allclose(switched.position, plain.position, atol=1e-5)  # an explicit runtime wins
    with pytest.raises(FileNotFoundError, match=r"no pretrained model 'slid' \(did you mean 'slide'\?\); the "
                                                r"pretrained models: slide"):
        api.load_simulator("slid")
