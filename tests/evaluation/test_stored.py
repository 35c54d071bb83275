"""The stored rollout and DEM ensemble member a sim is scored with: read back as stored (a blown-up rollout
included), and refused by name when another checkpoint or history made the rollout, or the member is not a rerun
of the sim's frames and particles starting from its given frames."""

import numpy as np
import pytest

from evaluation import stored
from generators import h5md

T, N, K = 6, 5, 3


def _sim(**extra) -> h5md.Trajectory:
    rng = np.random.default_rng(0)
    kinematic = np.arange(N) < 2
    fields = dict(position=(1.0 + np.cumsum(rng.normal(0, 0.01, (T, N, 2)), axis=0)).astype(np.float32),
                  time=0.1 * np.arange(T),
                  step=10 * np.arange(T), species=kinematic.astype(int) ^ 1, radius=np.full(N, 0.05),
                  mass=np.where(kinematic, 0.0, 1.0), kinematic=kinematic, box_lower=np.zeros(2),
                  box_upper=np.full(2, 2.0))
    fields.update(extra)
    return h5md.Trajectory(**fields)


def test_a_rollout_made_by_the_checkpoint_reads_back_blow_up_included(tmp_path):
    position = _sim().position.copy()
    position[4:, 3] = np.nan                                   # the rollout blew up at frame 4
    path = h5md.write(tmp_path / "r.h5", _sim(position=position, parameters={"rollout_checkpoint_sha": "abc",
                                                                               "rollout_history": K}),
                      allow_nonfinite=True)
    traj = stored.read_rollout(path, "abc", K)
    np.testing.assert_array_equal(traj.position, position)
    with pytest.raises(ValueError, match="made by checkpoint abc, not by def; rerun the rollout"):
        stored.read_rollout(path, "def", K)
    with pytest.raises(ValueError, match=f"given {K} frames, the evaluation 4; evaluate with --history {K}"):
        stored.read_rollout(path, "abc", 4)


def test_an_ensemble_member_starting_from_the_sim_s_given_frames_reads_back(tmp_path):
    sim = _sim()
    position = sim.position.copy()
    position[K:] += 1e-4                                       # it departs after the K given frames
    path = h5md.write(tmp_path / "m.h5", _sim(position=position))
    got = stored.read_ensemble(path, sim, K)
    np.testing.assert_array_equal(got, np.asarray(position, np.float64))
    with pytest.raises(ValueError, match=r"first 4 frames differ from the sim's \(largest difference 0.0001 m\)"):
        stored.read_ensemble(path, sim, K + 1)
    stored.read_ensemble(path, sim)                            # no history: the start is not checked
    with pytest.raises(FileNotFoundError, match="no DEM ensemble run of this sim"):
        stored.read_ensemble(tmp_path / "none.h5", sim)


@pytest.mark.parametrize("member, message", [
    (dict(position=_sim().position[:-1], time=0.1 * np.arange(T - 1), step=10 * np.arange(T - 1)),
     r"shape \(5, 5, 2\) differs from the sim's \(6, 5, 2\)"),
    (dict(time=0.1 * np.arange(T) + 0.01), "recorded at other times"),
    (dict(species=np.array([1, 1, 1, 1, 0])), "its particles .* differ from the sim's"),
])
def test_a_member_of_another_run_is_refused_by_name(tmp_path, member, message):
    path = h5md.write(tmp_path / "m.h5", _sim(**member))
    with pytest.raises(ValueError, match=message):
        stored.read_ensemble(path, _sim())
