"""graphdem's Python API: DEM sims as trajectories, training samples as a PyG dataset, trained surrogates.

From your own H5MD file to a rollout and its error::

    import graphdem
    sim = graphdem.load_sim("results/slide/sims/slide_0000.h5")
    simulator = graphdem.load_simulator("results/slide/model/best.pt")
    predicted = graphdem.rollout(simulator, sim)               # the first K frames given, the rest predicted
    print(graphdem.rollout_mse(predicted, sim))                # m², over the predicted frames

The pipeline's own code lives in three packages, the first two named in the article's vocabulary:
``generators`` (scenes, DEM engines, H5MD), ``surrogate`` (dataset, Graph-DEM, training, rollout) and
``evaluation`` (what measures a trained surrogate: metrics, baseline, tables, card, timings). The `graphdem`
command is graphdem/cli.py (docs/architecture.md, "Packages").

The names load on first use (torch and PyG take seconds to import), so that the command starts at once.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from generators.h5md import Trajectory
    from generators.h5md import read as load_sim
    from generators.h5md import write as save_sim
    from surrogate.api import load_simulator, rollout, rollout_mse
    from surrogate.pyg_dataset import SimDataset

#: each name of the API: (its module, its name there)
_API = {"SimDataset": ("surrogate.pyg_dataset", "SimDataset"), "Trajectory": ("generators.h5md", "Trajectory"),
        "load_sim": ("generators.h5md", "read"), "load_simulator": ("surrogate.api", "load_simulator"),
        "rollout": ("surrogate.api", "rollout"), "rollout_mse": ("surrogate.api", "rollout_mse"),
        "save_sim": ("generators.h5md", "write")}

__all__ = ["SimDataset", "Trajectory", "load_sim", "load_simulator", "rollout", "rollout_mse", "save_sim"]


def __getattr__(name: str):
    if name not in _API:
        raise AttributeError(f"module 'graphdem' has no attribute {name!r}")
    module, attr = _API[name]
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value                 # the next look-up finds it without this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
