"""graphdem's Python API: DEM sims as trajectories, training samples as a PyG dataset, trained surrogates.

From your own H5MD file to a rollout and its error::

    import graphdem
    sim = graphdem.load_sim("results/slide/sims/slide_0000.h5")
    simulator = graphdem.load_simulator("results/slide/model/best.pt")
    predicted = graphdem.rollout(simulator, sim)               # the first K frames given, the rest predicted
    print(graphdem.rollout_mse(predicted, sim))                # m², over the predicted frames

The pipeline's own code lives in two packages named in the article's vocabulary: ``generators`` (scenes,
DEM engines, H5MD) and ``surrogate`` (dataset, Graph-DEM, training, rollout, metrics).
"""

from generators.h5md import Trajectory
from generators.h5md import read as load_sim
from generators.h5md import write as save_sim
from surrogate.api import load_simulator, rollout, rollout_mse
from surrogate.pyg_dataset import SimDataset

__all__ = ["SimDataset", "Trajectory", "load_sim", "load_simulator", "rollout", "rollout_mse", "save_sim"]
