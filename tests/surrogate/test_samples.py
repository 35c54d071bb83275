import numpy as np
import pytest

from generators import h5md
from surrogate.samples import load_sim, normalised_properties, sample_index

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
