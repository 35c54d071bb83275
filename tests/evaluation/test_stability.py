"""Surrogate stability tests: blow-ups, escapes and precision are detected and reported, not hidden."""

from dataclasses import replace

import numpy as np
import pytest
import torch

from evaluation import stability
from surrogate import runtime
from surrogate.rollout import keep_in_domain, rollout

pytestmark = pytest.mark.engine

RT = runtime.Runtime(split_edge_mlp=True, skip_kinematic_pairs=True, prune_isolated=True, precision="float32",
                     sleep_speed=None, keep_in_domain=False, compile=False)


def test_error_growth_is_the_geometric_mean_ratio_per_step():
    assert stability.error_growth(np.array([1.0, 2.0, 4.0, 8.0])) == pytest.approx(2.0)
    assert np.isnan(stability.error_growth(np.array([0.0, 1.0])))


def test_a_clean_long_rollout_is_not_flagged(untrained):
    simulator, sim = untrained
    with torch.no_grad():
        simulator.acceleration_std.mul_(1e-6)            # a model that predicts (almost) free flight
        simulator.acceleration_mean.zero_()
    still = sim.position[: simulator.history].mean(dim=0, keepdim=True).repeat(sim.n_frames, 1, 1)
    resting = replace(sim, position=still)               # a packing at rest: nothing should move
    row, frames = stability.long_rollout(simulator, RT, resting, 3, 0.0, 0, max_overlap=10.0)
    assert row["stable"] and row["cause"] == "" and row["escaped_particles"] == 0
    assert row["n_frames"] == 3 * sim.n_frames and row["final_max_speed"] < 1e-3


def test_escaping_particles_are_counted_with_the_first_frame(untrained):
    simulator, sim = untrained
    with torch.no_grad():
        simulator.acceleration_std.mul_(1e-6)
        simulator.acceleration_mean.copy_(torch.tensor([3.0, 0.0]))   # every particle accelerates in +x
    row, frames = stability.long_rollout(simulator, RT, sim, 5, 0.01, 0, max_overlap=0.5)
    assert not row["stable"] and row["escaped_particles"] == int((~sim.kinematic).sum())
    assert f"left the bounds, the first at frame {row['first_escape_frame']}" in row["cause"]
    assert row["mse_growth_per_step"] > 1


def test_keep_in_domain_holds_the_same_escaping_particles_on_the_box_face(untrained):
    """The runtime switch keep_in_domain: the model that drives every particle out through +x (above)
    keeps them all in the box, each on the face it reached, and the clamps are counted."""
    simulator, sim = untrained
    with torch.no_grad():
        simulator.acceleration_std.mul_(1e-6)
        simulator.acceleration_mean.copy_(torch.tensor([3.0, 0.0]))
    walls = replace(RT, keep_in_domain=True)
    row, frames = stability.long_rollout(simulator, walls, sim, 5, 0.01, 0, max_overlap=0.5)
    assert row["escaped_particles"] == 0 and "left the bounds" not in row["cause"]
    result = rollout(simulator, sim, n_frames=5 * sim.n_frames, runtime=walls)
    moving = ~sim.kinematic.numpy()
    last = result.position[-1, moving]
    upper = simulator.upper.numpy()
    assert np.allclose(last[:, 0], upper[0])                    # every one stopped on the +x face
    assert np.all(last[:, 1] <= upper[1]) and np.all(last >= simulator.lower.numpy())
    assert result.timing["clamped"] > 0


def test_keep_in_domain_changes_nothing_inside_the_box(untrained):
    simulator, sim = untrained
    free = rollout(simulator, sim, runtime=RT)
    walls = rollout(simulator, sim, runtime=replace(RT, keep_in_domain=True))
    inside = np.all((free.position >= simulator.lower.numpy()) & (free.position <= simulator.upper.numpy()))
    assert inside and walls.timing["clamped"] == 0
    np.testing.assert_array_equal(free.position, walls.position)


def test_keep_in_domain_puts_back_only_moving_particles_outside():
    x = torch.tensor([[-0.5, 0.5], [0.5, 1.5], [0.2, 0.3], [2.0, 2.0]])
    moving = torch.tensor([True, True, True, False])
    lower, upper = torch.zeros(2), torch.ones(2)
    out, n = keep_in_domain(x, moving, lower, upper, clamped=4)
    assert n == 6
    assert torch.equal(out, torch.tensor([[0.0, 0.5], [0.5, 1.0], [0.2, 0.3], [2.0, 2.0]]))
    np.testing.assert_array_equal(x[0].numpy(), [-0.5, 0.5])   # the input is left as it was


def test_kinetic_energy_of_uniform_motion():
    # 2 moving particles of 2 and 3 kg at 0.1 m per frame of 0.05 s (2 m/s); a kinematic one ignored
    x = np.zeros((3, 3, 2))
    x[:, :, 0] = np.arange(3)[:, None] * 0.1
    energy = stability.kinetic_energy(x, np.array([2.0, 3.0, 100.0]), np.array([True, True, False]), 0.05)
    assert np.isnan(energy[0]) and energy[1:] == pytest.approx([0.5 * 5.0 * 4.0] * 2)


def test_the_envelope_names_the_first_frame_and_its_cause(untrained):
    simulator, sim = untrained
    lower, upper = simulator.lower.numpy().astype(float), simulator.upper.numpy().astype(float)
    data = np.asarray(sim.traj.position, float)
    peak = stability.data_energy_peak(sim)
    clean = stability.frame_table(data, sim, lower, upper, 1, max_overlap=0.5, energy_limit=2 * peak)
    assert clean["in_envelope"].all() and (clean["outside"] == 0).all()
    assert clean["max_overlap"].max() < 0.5 and (clean["p99_overlap"] <= clean["max_overlap"]).all()
    moving = ~sim.kinematic.numpy()
    hot = data.copy()
    hot[5:, moving] += (np.arange(5, len(hot))[:, None, None] - 4) * 0.5 * sim.traj.radius.mean()   # a kick at 5
    table = stability.frame_table(hot, sim, lower, upper, 1, max_overlap=0.5, energy_limit=2 * peak).set_index("frame")
    assert table.loc[:4, "in_envelope"].all() and not table.at[5, "in_envelope"]
    assert "kinetic energy above" in table.at[5, "envelope_cause"]
    squeezed = data.copy()
    first, second = np.flatnonzero(moving)[:2]
    squeezed[3:, second] = squeezed[3:, first] + [0.2 * sim.traj.radius[first], 0.0]    # deep overlap from 3
    table = stability.frame_table(squeezed, sim, lower, upper, 1, max_overlap=0.5, energy_limit=np.inf)
    assert table.set_index("frame").at[3, "envelope_cause"].startswith("overlap above 0.5 radii")
    assert table["max_overlap"].max() > 1.5


def test_a_particle_sent_through_a_wall_particle_is_counted_in_its_frame(untrained):
    """The moving particle nearest a kinematic one is carried, from frame 6 on, to its mirror image through that
    particle's centre: one passage at frame 6 and none after (it stays there); the data itself passes none."""
    simulator, sim = untrained
    lower, upper = simulator.lower.numpy().astype(float), simulator.upper.numpy().astype(float)
    data = np.asarray(sim.traj.position, float)
    clean = stability.frame_table(data, sim, lower, upper, 1, max_overlap=np.inf, energy_limit=np.inf)
    assert (clean["through_wall"] == 0).all()
    moving, kinematic = np.flatnonzero(~sim.kinematic.numpy()), np.flatnonzero(sim.kinematic.numpy())
    gaps = np.linalg.norm(data[5, moving][:, None] - data[5, kinematic][None], axis=-1)
    i, k = np.unravel_index(np.argmin(gaps), gaps.shape)
    passed = data.copy()
    passed[6:, moving[i]] = 2 * data[5, kinematic[k]] - data[5, moving[i]]
    table = stability.frame_table(passed, sim, lower, upper, 1, max_overlap=np.inf, energy_limit=np.inf)
    assert table.set_index("frame")["through_wall"].to_dict() == {t: int(t == 6) for t in range(1, len(data))}


def test_long_rollout_frames_cover_every_predicted_frame(untrained):
    simulator, sim = untrained
    row, frames = stability.long_rollout(simulator, RT, sim, 2, 0.0, 0, max_overlap=0.5, energy_envelope=2.0)
    assert list(frames["frame"]) == list(range(simulator.history, 2 * sim.n_frames))
    assert row["frames_outside_envelope"] == int((~frames["in_envelope"]).sum())
    if row["frames_outside_envelope"]:
        assert row["first_frame_outside_envelope"] == frames.loc[~frames["in_envelope"], "frame"].iloc[0]
    assert row["data_peak_kinetic_energy"] == pytest.approx(stability.data_energy_peak(sim))


def test_a_non_finite_rollout_is_named(untrained):
    simulator, sim = untrained
    with torch.no_grad():
        simulator.acceleration_std.fill_(float("inf"))
    row, frames = stability.long_rollout(simulator, RT, sim, 2, 0.0, 0, max_overlap=0.5)
    assert not row["stable"] and row["nonfinite_frame"] == simulator.history and "non-finite" in row["cause"]


def test_precision_rows_compare_with_float64(untrained):
    simulator, sim = untrained
    rows = {r["setting"]: r for r in stability.precision_rows(simulator, RT, sim)}
    assert rows["float64"]["max_difference_vs_float64"] == 0
    assert 0 < rows["float32"]["max_difference_vs_float64"] < 1e-3
    assert rows["float32"]["max_difference_vs_float64"] < rows["bfloat16"]["max_difference_vs_float64"]
