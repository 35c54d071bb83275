"""Surrogate stress tests: blow-ups, escapes and precision are detected and reported, not hidden."""

from dataclasses import replace

import numpy as np
import pytest
import torch

from surrogate import runtime, stability

pytestmark = pytest.mark.engine

RT = runtime.Runtime(split_edge_mlp=True, skip_kinematic_pairs=True, prune_isolated=True, precision="float32",
                     sleep_speed=None)


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
    row = stability.long_rollout(simulator, RT, resting, 3, 0.0, 0, max_overlap=10.0)
    assert row["stable"] and row["cause"] == "" and row["escaped_particles"] == 0
    assert row["n_frames"] == 3 * sim.n_frames and row["final_max_speed"] < 1e-3


def test_escaping_particles_are_counted_with_the_first_frame(untrained):
    simulator, sim = untrained
    with torch.no_grad():
        simulator.acceleration_std.mul_(1e-6)
        simulator.acceleration_mean.copy_(torch.tensor([3.0, 0.0]))   # every particle accelerates in +x
    row = stability.long_rollout(simulator, RT, sim, 5, 0.01, 0, max_overlap=0.5)
    assert not row["stable"] and row["escaped_particles"] == int((~sim.kinematic).sum())
    assert f"left the bounds, the first at frame {row['first_escape_frame']}" in row["cause"]
    assert row["mse_growth_per_step"] > 1


def test_a_non_finite_rollout_is_named(untrained):
    simulator, sim = untrained
    with torch.no_grad():
        simulator.acceleration_std.fill_(float("inf"))
    row = stability.long_rollout(simulator, RT, sim, 2, 0.0, 0, max_overlap=0.5)
    assert not row["stable"] and row["nonfinite_frame"] == simulator.history and "non-finite" in row["cause"]


def test_precision_rows_compare_with_float64(untrained):
    simulator, sim = untrained
    rows = {r["setting"]: r for r in stability.precision_rows(simulator, RT, sim)}
    assert rows["float64"]["max_difference_vs_float64"] == 0
    assert 0 < rows["float32"]["max_difference_vs_float64"] < 1e-3
    assert rows["float32"]["max_difference_vs_float64"] < rows["bfloat16"]["max_difference_vs_float64"]
