"""The radius-graph timing's packings (particles of unit diameter at the packing fraction asked for, the same
for the same seed) and its table (the edge count of each case, both methods timed)."""

import math

import numpy as np
import torch
from scipy.spatial import cKDTree

from evaluation.timing import graph
from surrogate.graph import radius_graph


def test_a_packing_has_the_fraction_s_density_and_repeats_with_its_seed():
    for dim in (2, 3):
        pos = graph.packing(1000, dim, seed=1)
        assert pos.shape == (1000, dim) and pos.dtype == torch.float32
        # lattice spacing a with a unit particle's area (volume) / a^dim = the fraction: pi/4 / a^2 = 0.8 in 2D
        ball = math.pi / 4 if dim == 2 else math.pi / 6
        spacing = (ball / graph.FRACTION[dim]) ** (1 / dim)
        nearest = cKDTree(pos.numpy()).query(pos.numpy(), k=2)[0][:, 1]
        # jittered by up to 0.1 a per axis: two lattice neighbours are at least a - 0.2 a apart, and the nearest
        # is no farther than the next along an axis, sqrt((1.2 a)^2 + (D - 1) (0.2 a)^2)
        assert 0.8 * spacing - 1e-6 <= nearest.min()
        assert nearest.max() <= math.sqrt(1.44 + 0.04 * (dim - 1)) * spacing + 1e-6
        assert abs(float(np.median(nearest)) / spacing - 1) < 0.1
        torch.testing.assert_close(graph.packing(1000, dim, seed=1), pos)
        assert not torch.equal(graph.packing(1000, dim, seed=2), pos)


def test_the_table_gives_each_case_s_edges_and_both_timings(capsys):
    threads = torch.get_num_threads()
    try:
        graph.main(["--repeats", "1", "--max-particles", "700"])
    finally:
        torch.set_num_threads(threads)          # main sets its --threads: none left to the next test
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| 2 |")]
    assert len(rows) == 1                                     # the one case of at most 700 particles
    cells = [c.strip() for c in rows[0].strip("|").split("|")]
    assert cells[:3] == ["2", "700", "2.5"]
    assert int(cells[3]) == radius_graph(graph.packing(700, 2), 2.5).shape[1]
    assert float(cells[5]) > 0 and float(cells[6]) > 0
