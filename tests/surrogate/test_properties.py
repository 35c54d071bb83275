"""A per-particle property (the shear scene's modulus) from the H5MD file to the model input."""

import math

import numpy as np
import pytest
import torch

from generators import h5md
from surrogate import dataset
from surrogate.graph import build_graph
from surrogate.samples import load_sim
from surrogate.simulator import LearnedSimulator


def write_sim(path, young: float, seed: int = 0):
    rng = np.random.default_rng(seed)
    n, t = 12, 8
    start = rng.uniform(0.01, 0.09, (n, 3))
    position = start[None] + np.cumsum(rng.normal(0, 1e-4, (t, n, 3)), axis=0)
    kinematic = np.arange(n) < 3
    position[:, kinematic] = start[None, kinematic]
    traj = h5md.Trajectory(
        position=position.astype(np.float32), time=np.arange(t) * 1e-3, step=np.arange(t) * 10,
        species=kinematic.astype(int) * 0 + (~kinematic).astype(int), radius=np.full(n, 0.004),
        mass=np.full(n, 7e-4), kinematic=kinematic, box_lower=np.zeros(3), box_upper=np.full(3, 0.1),
        boundary=("none",) * 3, properties=np.full((n, 1), young, np.float32), property_names=("young",),
        parameters={"scene": "shear", "log_scaled_properties": ["young"]})
    return h5md.write(path, traj)


def test_modulus_is_normalised_in_log_and_changes_the_model_input(tmp_path):
    paths = [write_sim(tmp_path / f"s{e:g}.h5", e, i) for i, e in enumerate((1e7, 1e8))]
    stats = dataset.statistics(paths, connectivity_radius=0.03)
    young = stats["property_stats"]["young"]
    assert young["log"] is True
    assert young["mean"] == pytest.approx(np.mean([math.log(1e7), math.log(1e8)]), rel=1e-12)
    assert young["std"] == pytest.approx(0.5 * math.log(10.0), rel=1e-12)
    soft, stiff = (load_sim(p, stats, ["young"]) for p in paths)
    assert torch.allclose(soft.props, torch.full_like(soft.props, -1.0), atol=1e-5)   # ln 1e7: one std below
    assert torch.allclose(stiff.props, torch.full_like(stiff.props, 1.0), atol=1e-5)

    torch.manual_seed(0)
    model = LearnedSimulator(stats, {"history": 6, "latent": 16, "hidden": 16, "message_passing": 2, "embed": 4,
                                     "mlp_layers": 2, "properties": ["young"]})
    window = soft.position[:6]
    a = model(build_graph(window, soft.types, soft.kinematic, model.radius, soft.props))
    b = model(build_graph(window, soft.types, soft.kinematic, model.radius, stiff.props))
    assert not torch.allclose(a, b)          # same positions, another modulus: another prediction


def test_scene_without_properties_has_no_property_feature(tmp_path):
    paths = [write_sim(tmp_path / "s.h5", 1e7)]
    stats = dataset.statistics(paths, connectivity_radius=0.03)
    sim = load_sim(paths[0], stats, [])
    assert sim.props is None
    model = LearnedSimulator(stats, {"history": 6, "latent": 8, "hidden": 8, "message_passing": 1, "embed": 4,
                                     "mlp_layers": 2, "properties": []})
    assert model.model.node_constructor.in_dim == 5 * 3 + 4 + 0 + 6
