"""The rollout timing script's table: its ratios, its graph sizes and its contact-miss rates (not its times)."""

import json

import numpy as np
import pandas as pd
import pytest

from evaluation.timing import rollout
from surrogate import contacts
from surrogate.samples import load_sim

pytestmark = pytest.mark.engine

CONFIGURED = {"split_edge_mlp": True, "skip_kinematic_pairs": True, "prune_isolated": True, "precision": "float32",
              "sleep_speed": None, "keep_in_domain": True, "compile": False}


@pytest.fixture
def saved(saved_checkpoint):
    """An initialised (seed 0) simulator saved as a checkpoint, the path of the first test sim, its statistics."""
    return saved_checkpoint


def test_the_table_has_every_batch_and_radius_with_its_graph_and_contact_misses(saved, tmp_path, capsys):
    path, sim_path, stats = saved
    out = tmp_path / "bench.csv"
    rollout.main(["--checkpoint", str(path), "--data", str(sim_path), "--repeats", "1", "--batches", "1", "3",
                  "--radius-factors", "1", "0.5", "--levers", "batch", "radius",
                  "--runtime-json", json.dumps(CONFIGURED), "--out", str(out)])
    printed = capsys.readouterr().out
    assert "timing only" in printed and "not meaningful without retraining" in printed
    table = pd.read_csv(out)
    assert list(table["variant"]) == ["eager", "batch 1", "batch 3", "R x 1", "R x 0.5"]
    rows = table.set_index("variant")
    assert rows.at["eager", "ratio_to_reference"] == 1.0 and rows.at["R x 1", "ratio_to_reference"] == 1.0
    assert (table["seconds_per_frame"] > 0).all()
    shares = table[["graph_share", "network_share", "rest_share"]]
    assert ((shares > 0) & (shares < 1)).all().all()
    np.testing.assert_allclose(shares.sum(axis=1), 1.0)
    # a batch computes the same graphs as the single rollouts
    assert rows.at["batch 3", "edges_per_step"] == pytest.approx(rows.at["eager", "edges_per_step"])
    sim = load_sim(sim_path, stats)
    radius = stats["connectivity_radius"]
    assert rows.at["R x 0.5", "radius"] == pytest.approx(radius / 2)
    assert rows.at["R x 0.5", "edges_per_step"] < rows.at["R x 1", "edges_per_step"]
    for name, r in (("R x 1", radius), ("R x 0.5", radius / 2)):
        expected = contacts.contact_miss_rate(sim.position.numpy(), sim.traj.radius, r, sim.kinematic.numpy())
        assert rows.at[name, "contact_miss_rate"] == pytest.approx(expected)
        assert rows.at[name, "edges_per_particle"] == pytest.approx(
            contacts.edges_per_particle(sim.position.numpy(), r, sim.kinematic.numpy()))
    assert rows.at["R x 0.5", "edges_per_particle"] < rows.at["R x 1", "edges_per_particle"]
    assert rows.at["R x 0.5", "contact_miss_rate"] >= rows.at["R x 1", "contact_miss_rate"]
