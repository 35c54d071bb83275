"""graphdem's Python API (graphdem/__init__.py): each name is the function it stands for, loaded on first use, and
the documented round trip, a saved model rolled out on a sim and the rollout scored, gives its numbers."""

import dataclasses
import subprocess
import sys

import numpy as np
import pytest

import graphdem
from generators import h5md
from surrogate import api, pyg_dataset

from .surrogate import saved


def test_each_name_is_the_function_it_stands_for_and_loads_on_first_use():
    assert graphdem.load_sim is h5md.read and graphdem.save_sim is h5md.write
    assert graphdem.Trajectory is h5md.Trajectory and graphdem.SimDataset is pyg_dataset.SimDataset
    assert graphdem.load_simulator is api.load_simulator and graphdem.rollout is api.rollout
    assert graphdem.rollout_mse is api.rollout_mse
    assert set(graphdem.__all__) <= set(dir(graphdem))
    with pytest.raises(AttributeError, match="module 'graphdem' has no attribute 'train'"):
        graphdem.train      # noqa: B018
    # importing graphdem alone imports neither torch nor the surrogate
    code = "import sys, graphdem; print('torch' in sys.modules, 'surrogate' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout.split() == \
        ["False", "False"]


def test_the_documented_round_trip_gives_the_rollout_and_its_error(tmp_path):
    data = saved.untrained(tmp_path)
    sim = graphdem.load_sim(data["paths"]["syn_03"])
    simulator = graphdem.load_simulator(data["checkpoint"])
    k = simulator.history
    predicted = graphdem.rollout(simulator, sim)
    np.testing.assert_array_equal(predicted.position[:k], sim.position[:k])          # the K frames given
    assert predicted.n_frames == sim.n_frames and predicted.parameters["rollout_history"] == k
    # a prediction off by (0.3, 0.4) m on every moving particle of every predicted frame: 0.3^2 + 0.4^2 = 0.25 m^2
    off = np.array(sim.position, np.float64)
    off[k:, ~sim.kinematic] += [0.3, 0.4]
    shifted = dataclasses.replace(predicted, position=off)
    assert graphdem.rollout_mse(shifted, sim) == pytest.approx(0.25, rel=1e-6)
    truth = dataclasses.replace(predicted, position=sim.position)
    assert graphdem.rollout_mse(truth, sim) == 0.0
    graphdem.save_sim(tmp_path / "rollout.h5", predicted)
    np.testing.assert_array_equal(graphdem.load_sim(tmp_path / "rollout.h5").position, predicted.position)
