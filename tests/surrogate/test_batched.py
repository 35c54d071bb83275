"""Batched rollouts: every sim of a batch rolls out as it would alone."""

import copy
from dataclasses import replace

import numpy as np
import pytest
import torch

from surrogate import batched, rollout, runtime
from surrogate.samples import load_sim
from surrogate.simulator import LearnedSimulator

pytestmark = pytest.mark.engine

PLAIN = runtime.Runtime(split_edge_mlp=False, skip_kinematic_pairs=True, prune_isolated=False, precision="float64",
                        sleep_speed=None, keep_in_domain=False, compile=False)
CONFIGURED = replace(PLAIN, split_edge_mlp=True, prune_isolated=True, precision="float32", keep_in_domain=True)


def subset(sim, keep, frames=None):
    """The sim with only the particles ``keep`` (and only its first ``frames`` frames)."""
    frames = frames or sim.n_frames
    return replace(sim, id=f"{sim.id}_subset", position=sim.position[:frames, keep].clone(), types=sim.types[keep],
                   kinematic=sim.kinematic[keep], props=None if sim.props is None else sim.props[keep])


def sims_of_several_sizes(tiny_dataset, untrained):
    """The test sim, a train sim without a fifth of its moving particles and cut short by two frames, and
    one without every third particle."""
    simulator, sim = untrained
    table = tiny_dataset["split_table"]
    other = load_sim(table.loc[table["split"] == "train", "path"].iloc[0], simulator.stats)
    moving = (~other.kinematic).nonzero().squeeze(1)
    dropped = moving[torch.randperm(len(moving), generator=torch.Generator().manual_seed(1))[:len(moving) // 5]]
    keep = torch.ones(len(other.kinematic), dtype=torch.bool)
    keep[dropped] = False
    every_third = torch.arange(len(sim.kinematic)) % 3 != 0
    return [sim, subset(other, keep, other.n_frames - 2), subset(sim, every_third)]


@pytest.mark.parametrize("rt, rtol", [(PLAIN, 1e-9), (CONFIGURED, 1e-5)], ids=["plain_float64", "configured"])
def test_each_batched_rollout_equals_its_single_rollout(tiny_dataset, untrained, rt, rtol):
    simulator, _ = untrained
    prepared = runtime.apply(copy.deepcopy(simulator), rt)
    sims = sims_of_several_sizes(tiny_dataset, untrained)
    assert len({s.position.shape[1] for s in sims}) == 3 and len({s.n_frames for s in sims}) == 2
    results = batched.rollout_batch(prepared, sims, rt)
    for sim, result in zip(sims, results, strict=True):
        single = rollout.rollout(prepared, sim, runtime=rt)
        assert result.position.shape == single.position.shape == (sim.n_frames, *sim.position.shape[1:])
        assert result.first_nonfinite is None and result.n_predicted == sim.n_frames - simulator.history
        k = simulator.history
        moved = np.abs(single.position[-1] - single.position[k - 1]).max()
        assert moved > 1e-3
        np.testing.assert_allclose(result.position, single.position, rtol=rtol, atol=rtol * moved)
        np.testing.assert_array_equal(result.position[:k], sim.position[:k].numpy())
        kinematic = sim.kinematic.numpy()
        np.testing.assert_array_equal(result.position[k:, kinematic], sim.position[k:, kinematic].numpy())
        assert {key: result.timing[key] for key in single.timing} == single.timing   # same graphs, same clamps
        assert result.timing["batch_size"] == 3
        assert result.seconds == pytest.approx(result.timing["batch_seconds"] / 3)


def test_a_sim_that_goes_non_finite_leaves_the_batch_alone(tiny_dataset, untrained):
    simulator, sim = untrained
    rt = replace(PLAIN, precision="float32")
    prepared = runtime.apply(copy.deepcopy(simulator), rt)
    k = simulator.history
    moving = int((~sim.kinematic).nonzero()[0, 0])
    position = sim.position.clone()
    position[k - 1, moving] = 3e38                      # its next position overflows float32
    bad = replace(sim, id="bad", position=position)
    good = sims_of_several_sizes(tiny_dataset, untrained)[1]
    results = batched.rollout_batch(prepared, [bad, good], rt)
    single_bad, single_good = (rollout.rollout(prepared, s, runtime=rt) for s in (bad, good))
    assert results[0].first_nonfinite == single_bad.first_nonfinite == k
    assert np.isnan(results[0].position[k:]).all() and results[0].n_predicted == 1
    assert results[1].first_nonfinite is None
    np.testing.assert_allclose(results[1].position, single_good.position, rtol=1e-5, atol=1e-5)


def test_keep_in_domain_is_applied_per_sim(untrained):
    simulator, sim = untrained
    rt = replace(CONFIGURED, keep_in_domain=True)
    prepared = runtime.apply(copy.deepcopy(simulator), rt)
    k = simulator.history
    moving = (~sim.kinematic).nonzero().squeeze(1)[:3]
    position = sim.position.clone()
    step = torch.zeros(position.shape[-1])
    step[0] = 0.5 * (simulator.upper[0] - simulator.lower[0]) / k      # these leave the box within two steps
    for f in range(k):
        position[f, moving] = simulator.upper - 1e-3 + step * (f - k + 1)
    leaving = replace(sim, id="leaving", position=position)
    results = batched.rollout_batch(prepared, [sim, leaving], rt)
    singles = [rollout.rollout(prepared, s, runtime=rt) for s in (sim, leaving)]
    assert results[1].timing["clamped"] == singles[1].timing["clamped"] > 0
    assert results[0].timing["clamped"] == singles[0].timing["clamped"]
    upper = simulator.upper.numpy()
    assert (results[1].position[k:, moving.numpy()] <= upper + 1e-6).all()
    for result, single in zip(results, singles, strict=True):
        np.testing.assert_allclose(result.position, single.position, rtol=1e-5, atol=1e-4)


def test_a_bundled_model_rolls_out_in_a_batch_as_alone(tiny_dataset, untrained):
    """Three frames per call over sims of 6 and 4 predicted frames (two calls each, the last frame of the
    shorter sim's second call dropped): every batched rollout equals its single rollout."""
    simulator, _ = untrained
    torch.manual_seed(0)
    bundled = LearnedSimulator(simulator.stats, {**simulator.model_config, "bundle": 3}).eval()
    prepared = runtime.apply(bundled, PLAIN)
    sims = sims_of_several_sizes(tiny_dataset, untrained)
    results = batched.rollout_batch(prepared, sims, PLAIN)
    for sim, result in zip(sims, results, strict=True):
        single = rollout.rollout(prepared, sim, runtime=PLAIN)
        assert result.n_predicted == single.n_predicted == sim.n_frames - prepared.history
        k = prepared.history
        moved = np.abs(single.position[-1] - single.position[k - 1]).max()
        assert moved > 1e-3
        np.testing.assert_allclose(result.position, single.position, rtol=1e-9, atol=1e-9 * moved)
        assert {key: result.timing[key] for key in single.timing} == single.timing
