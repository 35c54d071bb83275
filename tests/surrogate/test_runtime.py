"""Runtime switches of a rollout: exact ones change nothing, sleeping holds only particles at rest."""

import copy
from dataclasses import replace

import numpy as np
import pytest
import torch

from surrogate import rollout, runtime

pytestmark = pytest.mark.engine

PLAIN = runtime.Runtime(split_edge_mlp=False, skip_kinematic_pairs=True, prune_isolated=False, precision="float64",
                        sleep_speed=None, keep_in_domain=False, compile=False)


def prepared(simulator, rt):
    return runtime.apply(copy.deepcopy(simulator), rt)


def test_exact_switches_leave_the_rollout_unchanged(untrained):
    simulator, sim = untrained
    reference = rollout.rollout(prepared(simulator, PLAIN), sim, runtime=PLAIN)
    fast = replace(PLAIN, split_edge_mlp=True, prune_isolated=True)
    result = rollout.rollout(prepared(simulator, fast), sim, runtime=fast)
    assert result.position.dtype == np.float64
    np.testing.assert_allclose(result.position, reference.position, rtol=0, atol=1e-9)
    assert result.timing["nodes_per_step"] < reference.timing["nodes_per_step"]     # isolated walls left out
    assert result.timing["edges_per_step"] < reference.timing["edges_per_step"]


def test_float32_and_bfloat16_rollouts_stay_close_to_float64(untrained):
    simulator, sim = untrained
    reference = rollout.rollout(prepared(simulator, PLAIN), sim, runtime=PLAIN).position
    spread = np.abs(reference[-1] - reference[0]).max()
    for precision, tolerance in (("float32", 1e-4), ("bfloat16", 0.1)):
        rt = replace(PLAIN, precision=precision)
        position = rollout.rollout(prepared(simulator, rt), sim, runtime=rt).position
        assert position.dtype == np.float32
        difference = np.abs(position - reference).max()
        assert 0 < difference < tolerance * max(spread, 1.0), precision


def test_unknown_precision_and_keys_are_refused():
    with pytest.raises(ValueError, match="precision = 'half'.*float64, float32, bfloat16"):
        replace(PLAIN, precision="half")
    with pytest.raises(ValueError, match=r"unknown keys \['sleep'\]"):
        runtime.Runtime.from_config({**PLAIN.as_dict(), "sleep": True})


def two_clusters(simulator, sim):
    """The real sim's particles, with a resting block far from a moving one and one resting
    particle just inside R of the moving block."""
    k = simulator.history
    moving = (~sim.kinematic).nonzero().squeeze(1)
    base = sim.position[0].clone()
    frames = base.repeat(k + 3, 1, 1)
    fast, rest = moving[:5], moving[5:]
    for f in range(k + 3):                           # the fast block moves 1 m per frame in x
        frames[f, fast] = base[fast] + torch.tensor([1.0 * f, 0.0])
    near = rest[0]
    frames[:, near] = frames[k - 1, fast[0]] + torch.tensor([0.0, 0.6 * simulator.radius])
    return replace(sim, position=frames), fast, rest, near


def test_sleeping_particles_hold_still_and_wake_near_motion(untrained):
    simulator, sim = untrained
    crafted, fast, rest, near = two_clusters(simulator, sim)
    rt = replace(PLAIN, prune_isolated=True, sleep_speed=1e-3)
    result = rollout.rollout(prepared(simulator, rt), crafted, runtime=rt)
    k = simulator.history
    distance = torch.cdist(crafted.position[k - 1, rest], crafted.position[k - 1, fast]).min(dim=1).values
    far = rest[distance > 3 * simulator.radius]
    assert len(far) > 0 and result.timing["asleep_per_step"] > 0
    np.testing.assert_array_equal(result.position[k, far], crafted.position[k - 1, far].double().numpy())
    assert not np.allclose(result.position[k, near], crafted.position[k - 1, near].double().numpy())   # woken
    awake_only = rollout.rollout(prepared(simulator, PLAIN), crafted, runtime=PLAIN)
    np.testing.assert_allclose(result.position[k, fast], awake_only.position[k, fast], atol=0.05 * 1.0)


def test_kinematic_pairs_add_edges_and_change_the_input_of_a_model_trained_without_them(untrained):
    simulator, sim = untrained
    paired = replace(PLAIN, skip_kinematic_pairs=False)
    reference = rollout.rollout(prepared(simulator, PLAIN), sim, runtime=PLAIN)
    result = rollout.rollout(prepared(simulator, paired), sim, runtime=paired)
    assert result.timing["edges_per_step"] > reference.timing["edges_per_step"]
    assert not np.allclose(result.position, reference.position)
    with pytest.raises(ValueError, match="need runtime.skip_kinematic_pairs = true"):
        replace(PLAIN, skip_kinematic_pairs=False, prune_isolated=True)


def test_compiled_rollout_equals_the_eager_one_to_float32_rounding(untrained):
    simulator, sim = untrained
    from torch._dynamo.utils import counters
    for base in (replace(PLAIN, precision="float32", keep_in_domain=True),                 # whole graph decoded
                 replace(PLAIN, precision="float32", split_edge_mlp=True, prune_isolated=True)):   # a subset
        compiled = replace(base, compile=True)
        eager = rollout.rollout(prepared(simulator, base), sim, runtime=base)
        before = counters["stats"]["unique_graphs"]
        result = rollout.rollout(prepared(simulator, compiled), sim, runtime=compiled)
        assert counters["stats"]["unique_graphs"] > before                    # it did compile the forward pass
        assert result.first_nonfinite is None and result.timing == eager.timing
        moved = np.abs(eager.position[-1] - eager.position[simulator.history - 1]).max()
        assert moved > 1e-3                                                   # the rollout predicts motion
        np.testing.assert_allclose(result.position, eager.position, rtol=1e-5, atol=1e-5 * moved)
    assert runtime.Runtime.from_config({**PLAIN.as_dict(), "compile": True}).compile
