"""The training samples of a split as a PyTorch Geometric ``Dataset`` (article 5.4.3).

Sample ``i`` is one (sim, frame t) of the split: the history window ``p^{t-K+1..t}``, the next frame
``p^{t+1}`` and the radius graph of frame t, as a :class:`torch_geometric.data.Data`:

=============  ==========  ===================================================================
``pos``        [N, D]      positions at frame t (m)
``history``    [N, K, D]   the window of K frames, oldest first (m)
``y``          [N, D]      positions at frame t+1 (m), the prediction target
``edge_index`` [2, E]      senders, receivers: every pair closer than R plus self edges, none
                           between two kinematic particles, each receiver's ``max_neighbours``
                           nearest senders where that cap is given (the model's graph)
``types``      [N]         particle species
``kinematic``  [N]         True where the position is prescribed (never predicted)
``props``      [N, F]      the model's node properties, z-scored with the train statistics
=============  ==========  ===================================================================

Batches from :class:`torch_geometric.loader.DataLoader` stack samples along the particle axis, as
the trainer does.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
from torch_geometric.data import Data, Dataset

from surrogate.graph import build_graph
from surrogate.neighbours import check_cap
from surrogate.samples import load_sim, sample_index


class SimDataset(Dataset):
    """Samples of one split of a dataset's split table, sims held in memory.

    Args:
        splits: the dataset's ``splits.csv`` (columns ``id``, ``split``, ``path``), or that table.
        stats: the dataset's ``stats.json`` (or its dict): normalisation statistics, radius R, properties.
        split: ``train``, ``valid`` or ``test``.
        history: K, the frames a sample's window holds.
        properties: node properties to give each sample (names in ``stats.json``); none by default.
        max_neighbours: the model's neighbour cap (senders kept per receiver); none by default.
    """

    def __init__(self, splits: str | Path | pd.DataFrame, stats: str | Path | dict, split: str = "train",
                 history: int = 6, properties: list[str] | None = None, max_neighbours: int | None = None):
        super().__init__()
        table = splits if isinstance(splits, pd.DataFrame) else pd.read_csv(splits)
        self.stats = stats if isinstance(stats, dict) else json.loads(Path(stats).read_text())
        rows = table[table["split"] == split]
        if rows.empty:
            raise ValueError(f"the split table has no {split!r} sims; splits: {sorted(table['split'].unique())}")
        self.history = int(history)
        self.radius = float(self.stats["connectivity_radius"])
        self.max_neighbours = check_cap(max_neighbours)
        self.sims = [load_sim(path, self.stats, properties) for path in rows["path"]]
        self.index = sample_index(self.sims, self.history)

    def len(self) -> int:
        return len(self.index)

    def get(self, idx: int) -> Data:
        s, t = self.index[idx]
        sim = self.sims[s]
        window = sim.position[t - self.history + 1:t + 1]
        graph = build_graph(window, sim.types, sim.kinematic, self.radius, sim.props,
                            max_neighbours=self.max_neighbours)
        data = Data(pos=window[-1], history=window.transpose(0, 1).contiguous(), y=sim.position[t + 1],
                    edge_index=graph.edge_index, types=sim.types, kinematic=sim.kinematic)
        if sim.props is not None:
            data.props = sim.props
        data.sim, data.frame = sim.id, t
        return data
