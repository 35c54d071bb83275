import numpy as np
import pytest
import torch

from generators import h5md
from surrogate.samples import (
    activity_weights,
    data_files,
    epoch_activity_weight,
    epoch_order,
    load_sim,
    normalised_properties,
    sample_activity,
    sample_index,
)

STATS = {"dim": 2, "n_types": 2, "property_stats": {"radius": {"mean": 0.5, "std": 0.1, "log": False},
                                                     "young": {"mean": np.log(1e8), "std": 2.0, "log": True}}}


def trajectory(frames=7):
    return h5md.Trajectory(
        position=np.zeros((frames, 3, 2)) + np.arange(3)[None, :, None], time=np.arange(frames) * 0.1,
        step=np.arange(frames), species=np.array([1, 1, 0]), radius=np.array([0.4, 0.6, 0.5]), mass=np.ones(3),
        kinematic=np.array([False, False, True]), box_lower=np.zeros(2), box_upper=np.full(2, 10.0),
        properties=np.array([[1e8], [1e9], [1e8]]), property_names=("young",))


def test_properties_are_z_scored_and_log_scaled_where_the_stats_say_so():
    props = normalised_properties(trajectory(), ["radius", "young"], STATS).numpy()
    np.testing.assert_allclose(props[:, 0], [-1.0, 1.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(props[:, 1], [0.0, np.log(10) / 2, 0.0], atol=1e-6)
    assert normalised_properties(trajectory(), [], STATS) is None       # no property, no feature


def test_unknown_property_is_named_with_what_is_allowed():
    with pytest.raises(ValueError, match="node property 'porosity' is not in the data: allowed 'radius' or one of"):
        normalised_properties(trajectory(), ["porosity"], {"property_stats": {"porosity": {"mean": 0, "std": 1}}})


def test_every_frame_with_a_successor_is_a_sample(tmp_path):
    h5md.write(tmp_path / "a.h5", trajectory(7))
    sim = load_sim(tmp_path / "a.h5", STATS)
    assert sample_index([sim], history=6) == [(0, 5)]
    assert sample_index([sim, sim], history=3) == [(0, t) for t in range(2, 6)] + [(1, t) for t in range(2, 6)]
    with pytest.raises(ValueError, match="7 frames cannot give a history of 7"):
        sample_index([sim], history=7)
    assert sample_index([sim], history=3, bundle=2) == [(0, t) for t in range(2, 5)]     # two frames to predict
    with pytest.raises(ValueError, match="7 frames cannot give a history of 6 plus 2 target frame"):
        sample_index([sim], history=6, bundle=2)


def test_activity_is_the_mean_squared_target_acceleration_of_the_moving_particles(tmp_path):
    traj = trajectory(7)
    # particle 0 falls freely from frame 2 on (acceleration -0.5 per frame^2 in y); particle 1 rests;
    # the kinematic particle 2 jumps about, which must not count
    frames = np.arange(7)
    traj.position[:, 0, 1] = -0.25 * np.clip(frames - 2, 0, None) ** 2
    traj.position[:, 2, 0] += np.array([0, 3, -2, 5, 0, 1, 4])
    h5md.write(tmp_path / "a.h5", traj)
    sim = load_sim(tmp_path / "a.h5", STATS)
    index = sample_index([sim], history=2)              # t = 1 .. 5
    activity = sample_activity([sim], index)
    # target of sample t: p(t+1) - 2 p(t) + p(t-1); the fall starts at t = 2 (p(3) - 2 p(2) + p(1) = -0.25)
    expected = [0.0, 0.25 ** 2 / 2, 0.5 ** 2 / 2, 0.5 ** 2 / 2, 0.5 ** 2 / 2]
    np.testing.assert_allclose(activity, expected, rtol=1e-6)
    # two sims: each sample keeps its own sim's value
    np.testing.assert_allclose(sample_activity([sim, sim], sample_index([sim, sim], 2)), expected * 2, rtol=1e-6)


def test_activity_weights_follow_the_rule_and_zero_keeps_uniform_epochs():
    activity = np.array([0.0, 1.0, 3.0])               # mean 4/3
    assert activity_weights(activity, 0.0) is None
    assert activity_weights(np.zeros(3), 2.0) is None   # nothing moves: every sample alike
    np.testing.assert_allclose(activity_weights(activity, 2.0).numpy(), [1.0, 2.5, 5.5])
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="train.activity_weight must be a finite number >= 0"):
            activity_weights(activity, bad)


def test_the_activity_weight_runs_linearly_to_its_final_value_over_the_epochs():
    # absent final: the same weight every epoch
    assert [epoch_activity_weight(4.0, None, e, 10) for e in range(10)] == [4.0] * 10
    # 4 -> 0 over 10 epochs: 4 at the first, 0 at the last, steps of 4/9 between
    schedule = [epoch_activity_weight(4.0, 0.0, e, 10) for e in range(10)]
    assert schedule[0] == 4.0 and schedule[-1] == 0.0
    np.testing.assert_allclose(np.diff(schedule), -4.0 / 9.0)
    assert epoch_activity_weight(0.0, 2.0, 1, 3) == 1.0                 # it can rise as well
    assert epoch_activity_weight(4.0, 0.0, 0, 1) == 4.0                 # one epoch: the first value
    # a weight of 0 at the end is the uniform epoch of activity_weights
    assert activity_weights(np.array([0.0, 1.0, 3.0]), schedule[-1]) is None


def test_epoch_order_is_a_permutation_or_draws_in_proportion_to_the_weights():
    gen = torch.Generator().manual_seed(3)
    assert sorted(epoch_order(50, None, gen)) == list(range(50))
    weights = torch.tensor([1.0, 3.0, 0.0, 4.0])
    drawn = np.bincount(epoch_order(40000, weights, torch.Generator().manual_seed(3)), minlength=4) / 40000
    np.testing.assert_allclose(drawn, [0.125, 0.375, 0.0, 0.5], atol=0.01)
    # the same generator state gives the same epoch (a resumed run draws what the uninterrupted one drew)
    assert epoch_order(20, weights, torch.Generator().manual_seed(9)) == epoch_order(20, weights,
                                                                                     torch.Generator().manual_seed(9))


def test_a_folder_of_sims_is_read_without_hidden_temporaries(tmp_path):
    for name in ("slide_0001.h5", "slide_0000.h5", ".slide_0002.tmp-4242.h5", "notes.txt"):
        (tmp_path / name).write_bytes(b"")
    assert [p.name for p in data_files([tmp_path])] == ["slide_0000.h5", "slide_0001.h5"]
