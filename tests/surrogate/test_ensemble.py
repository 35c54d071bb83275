"""Seed ensembles at inference: every step the mean of the models' physical accelerations is integrated once."""

import copy

import h5py
import numpy as np
import pandas as pd
import pytest
import torch

from evaluation import evaluate
from graphdem import cli
from surrogate import checkpoint, ensemble
from surrogate import runtime as rt
from surrogate.batched import rollout_batch
from surrogate.ensemble import Ensemble
from surrogate.graph import build_graph, prune_isolated
from surrogate.rollout import rollout
from surrogate.samples import load_sim
from surrogate.simulator import LearnedSimulator, advance
from tests.surrogate import synthetic

RUNTIMES = {
    "none": None,
    "pruned": rt.Runtime(split_edge_mlp=True, skip_kinematic_pairs=True, prune_isolated=True, precision="float32",
                         sleep_speed=None, keep_in_domain=True, compile=False),
    "float64": rt.Runtime(split_edge_mlp=False, skip_kinematic_pairs=True, prune_isolated=False, precision="float64",
                          sleep_speed=None, keep_in_domain=False, compile=False),
}


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return synthetic.build(tmp_path_factory.mktemp("synthetic"))


def model(stats: dict, seed: int, **changes) -> LearnedSimulator:
    torch.manual_seed(seed)
    return LearnedSimulator(stats, {**synthetic.MODEL, **changes}).eval()


def sim_of(data, name="syn_03"):
    return load_sim(data["paths"][name], data["stats"])


def prepared(simulator, runtime):
    simulator = copy.deepcopy(simulator)
    return simulator if runtime is None else rt.apply(simulator, runtime)


@pytest.mark.parametrize("runtime", RUNTIMES)
def test_an_ensemble_of_one_model_rolls_out_bit_for_bit_as_the_model(data, runtime):
    runtime, m, sim = RUNTIMES[runtime], model(data["stats"], 0), sim_of(data)
    single = rollout(prepared(m, runtime), sim, runtime=runtime)
    one = rollout(prepared(Ensemble([m]), runtime), sim, runtime=runtime)
    np.testing.assert_array_equal(one.position, single.position)
    assert (one.models, single.models) == (1, 1) and one.first_nonfinite is None


def test_an_ensemble_of_one_model_batched_is_the_models_batch_bit_for_bit(data):
    runtime, m = RUNTIMES["pruned"], model(data["stats"], 0)
    sims = [sim_of(data, "syn_03"), sim_of(data, "syn_02")]
    single = rollout_batch(prepared(m, runtime), sims, runtime)
    one = rollout_batch(prepared(Ensemble([m]), runtime), sims, runtime)
    for a, b in zip(one, single, strict=True):
        np.testing.assert_array_equal(a.position, b.position)


@pytest.mark.parametrize("runtime", ["none", "pruned"])
def test_the_same_model_twice_rolls_out_as_the_model_to_rounding(data, runtime):
    runtime, m, sim = RUNTIMES[runtime], model(data["stats"], 0), sim_of(data)
    single = rollout(prepared(m, runtime), sim, runtime=runtime)
    twice = rollout(prepared(Ensemble([m, copy.deepcopy(m)]), runtime), sim, runtime=runtime)
    np.testing.assert_allclose(twice.position, single.position, rtol=0, atol=1e-6)
    assert twice.models == 2


def test_two_models_step_with_exactly_the_mean_of_their_accelerations(data):
    """The first predicted frame of two different (randomly initialised) models: the last frame plus its
    velocity plus the mean of the two models' physical accelerations on the first graph."""
    a, b, sim = model(data["stats"], 1), model(data["stats"], 2), sim_of(data)
    k = a.history
    result = rollout(Ensemble([a, b]), sim, n_frames=k + 1)
    window = sim.position[:k]
    reduced, index = prune_isolated(build_graph(window, sim.types, sim.kinematic, a.radius))
    moving = (~reduced.kinematic).nonzero().squeeze(1)
    with torch.no_grad():
        accelerations = [m.denormalise(m(reduced, decode=moving)) for m in (a, b)]
    mean = (accelerations[0] + accelerations[1]) / 2
    expected = advance(reduced.window[:, moving], mean)[0]
    assert not torch.allclose(accelerations[0], accelerations[1])          # two different models
    assert torch.equal(torch.from_numpy(result.position[k][index[moving].numpy()]), expected)
    each = [advance(reduced.window[:, moving], acc)[0] for acc in accelerations]
    torch.testing.assert_close(expected, (each[0] + each[1]) / 2)          # between the two models' own steps


def test_two_bundled_models_step_with_the_mean_of_their_accelerations_over_the_bundle(data):
    """Two frames per call: both predicted frames of the ensemble's first call are eq. (1) applied twice to the
    mean of the two models' physical accelerations of each frame."""
    a, b, sim = model(data["stats"], 1, bundle=2), model(data["stats"], 2, bundle=2), sim_of(data)
    k = a.history
    result = rollout(Ensemble([a, b]), sim, n_frames=k + 2)
    reduced, index = prune_isolated(build_graph(sim.position[:k], sim.types, sim.kinematic, a.radius))
    moving = (~reduced.kinematic).nonzero().squeeze(1)
    with torch.no_grad():
        mean = sum(m.denormalise(m(reduced, decode=moving)) for m in (a, b)) / 2
    assert mean.shape == (len(moving), 4)
    expected = advance(reduced.window[:, moving], mean)
    np.testing.assert_allclose(result.position[k:k + 2][:, index[moving].numpy()], expected.numpy(), rtol=1e-6,
                               atol=1e-6)


def test_models_with_other_statistics_of_motion_but_the_same_inputs_are_an_ensemble(data):
    """Each model normalises its own inputs and outputs: other velocity and acceleration statistics are allowed."""
    other = {**data["stats"], "acceleration_std": [2 * s for s in data["stats"]["acceleration_std"]],
             "velocity_mean": [0.0, 0.0]}
    Ensemble([model(data["stats"], 0), model(other, 1)])


@pytest.mark.parametrize("key, model_change, stats_change", [
    ("model.history", {"history": 4}, {}),
    ("model.max_neighbours", {"max_neighbours": 4}, {}),
    ("model.bundle", {"bundle": 2}, {}),
    ("stats.connectivity_radius", {}, {"connectivity_radius": 2.0}),
    ("stats.frame_interval", {}, {"frame_interval": 0.2}),
    ("stats.bounds", {}, {"bounds": [[0.0, 20.0], [0.0, 16.0]]}),
    ("stats.n_types", {}, {"n_types": 3}),
])
def test_models_that_read_other_inputs_are_refused_naming_the_key(data, key, model_change, stats_change):
    base = model(data["stats"], 0)
    other = model({**data["stats"], **stats_change}, 1, **model_change)
    with pytest.raises(ValueError, match=rf"ensemble: b.pt has {key} = .*, a.pt .*; the models of an ensemble must "
                                         r"share model.history"):
        Ensemble([base, other], ["a.pt", "b.pt"])


def save(path, simulator: LearnedSimulator) -> None:
    checkpoint.save(path, {"model": simulator.state_dict(), "json": {
        "model": simulator.model_config, "train": {"seed": 0}, "stats": simulator.stats}})


def test_the_cli_rolls_out_and_evaluates_an_ensemble_and_records_its_models(data, tmp_path, capsys):
    paths = [tmp_path / "a.pt", tmp_path / "b.pt"]
    save(paths[0], model(data["stats"], 1))
    save(paths[1], model(data["stats"], 2))
    test_sim = data["paths"]["syn_03"]
    assert cli.main(["rollout", "--checkpoint", *map(str, paths), "--data", str(test_sim),
                     "--out-dir", str(tmp_path / "rollouts"), "--device", "cpu"]) == 0
    assert "ms per frame, 2 models averaged" in capsys.readouterr().out
    with h5py.File(tmp_path / "rollouts" / "syn_03.h5", "r") as f:
        names = set(f["parameters"].attrs) | set(f["parameters"])
    assert {"rollout_models", "rollout_checkpoint"} <= names
    loaded, metas = ensemble.load(paths)
    assert isinstance(loaded, Ensemble) and loaded.n_models == 2 and len(metas) == 2
    direct = rollout(loaded, sim_of(data))
    written = load_sim(tmp_path / "rollouts" / "syn_03.h5", data["stats"], allow_other_scene=True)
    np.testing.assert_array_equal(written.position.numpy(), direct.position.astype(np.float32))
    # evaluate: the ensemble is Graph-DEM, named by both checkpoints, and its cost is its own
    assert cli.main(["evaluate", "--checkpoint", *map(str, paths), "--data", str(test_sim), "--history", "3",
                     "--out", str(tmp_path / "m.csv"), "--no-progress", "--device", "cpu"]) == 0
    table = pd.read_csv(tmp_path / "m.csv")
    assert set(table["checkpoint"]) == {f"{paths[0]} {paths[1]}"}
    assert set(table["checkpoint_sha"]) == {f"{checkpoint.digest(paths[0])}+{checkpoint.digest(paths[1])}"}
    seconds = table[table["metric"] == evaluate.SECONDS]["mean_prediction"]
    assert len(seconds) == 1 and seconds.iloc[0] > 0
    mse = table[(table["metric"] == evaluate.MSE) & (table["method"] == evaluate.MODEL) & (table["sim"] == "all")]
    truth = sim_of(data).position.numpy()
    assert mse["mse"].iloc[0] == pytest.approx(float(((direct.position[3:, :36] - truth[3:, :36]) ** 2).sum(-1).mean()))


def test_the_cli_refuses_an_ensemble_of_mismatched_models_naming_the_key(data, tmp_path, capsys):
    paths = [tmp_path / "a.pt", tmp_path / "b.pt"]
    save(paths[0], model(data["stats"], 1))
    save(paths[1], model(data["stats"], 2, history=4))
    assert cli.main(["rollout", "--checkpoint", *map(str, paths), "--data", str(data["paths"]["syn_03"]),
                     "--out-dir", str(tmp_path / "rollouts"), "--device", "cpu"]) == 1
    err = capsys.readouterr().err
    assert f"graphdem rollout: error: ensemble: {paths[1]} has model.history = 4, {paths[0]} 3" in err
    assert not (tmp_path / "rollouts").exists()
