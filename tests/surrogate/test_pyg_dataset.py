"""The PyG dataset of a split: windows, targets and graphs of every (sim, frame), checked against the data."""

import json

import numpy as np
import pytest
from scipy.spatial.distance import cdist
from torch_geometric.loader import DataLoader

from generators import h5md
from surrogate.pyg_dataset import SimDataset

pytestmark = pytest.mark.engine


def test_every_sample_is_a_window_its_next_frame_and_its_radius_graph(tiny_dataset):
    data = SimDataset(tiny_dataset["splits"], tiny_dataset["stats_path"], split="train", history=4)
    table = tiny_dataset["split_table"]
    train = table[table["split"] == "train"]
    trajs = [h5md.read(p) for p in train["path"]]
    assert len(data) == sum(t.n_frames - 4 for t in trajs)          # T - K samples per sim
    last = data[len(data) - 1]
    traj = trajs[-1]
    t = traj.n_frames - 2
    assert last.sim == train["id"].iloc[-1] and last.frame == t
    np.testing.assert_array_equal(last.pos.numpy(), traj.position[t])
    np.testing.assert_array_equal(last.y.numpy(), traj.position[t + 1])
    np.testing.assert_array_equal(last.history.numpy(), traj.position[t - 3:t + 1].transpose(1, 0, 2))
    # the graph: every pair closer than R, both ways, a self edge per node, no kinematic-kinematic pair
    radius = json.loads(tiny_dataset["stats_json"])["connectivity_radius"]
    close = cdist(traj.position[t], traj.position[t]) < radius
    close &= ~np.outer(traj.kinematic, traj.kinematic)
    np.fill_diagonal(close, True)
    edges = set(map(tuple, last.edge_index.numpy().T))
    assert edges == set(zip(*np.nonzero(close), strict=True)) and last.edge_index.shape[1] == len(edges)


def test_a_loader_stacks_samples_along_the_particle_axis(tiny_dataset):
    data = SimDataset(tiny_dataset["splits"], tiny_dataset["stats_path"], split="valid", history=4)
    batch = next(iter(DataLoader(data, batch_size=2)))
    n = data[0].num_nodes
    assert batch.num_nodes == 2 * n and batch.history.shape == (2 * n, 4, 2)
    assert batch.edge_index.shape[1] == data[0].edge_index.shape[1] + data[1].edge_index.shape[1]
    assert int(batch.edge_index[:, data[0].edge_index.shape[1]:].min()) >= n      # second sample offset


def test_a_split_without_sims_is_named(tiny_dataset):
    with pytest.raises(ValueError, match="no 'holdout' sims; splits: \\['test', 'train', 'valid'\\]"):
        SimDataset(tiny_dataset["splits"], tiny_dataset["stats_path"], split="holdout")
