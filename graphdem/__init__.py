"""graphdem's Python API: DEM sims as trajectories, training samples as a PyG dataset, trained surrogates.

From an H5MD file to a rollout and its error, with the pretrained slide model the package ships (or your own
``results/slide/model/best.pt``)::

    import graphdem
    sim = graphdem.load_sim(graphdem.example_sim("slide"))     # or your own H5MD file
    simulator = graphdem.load_simulator("slide")
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
    from surrogate.pretrained import example as example_sim
    from surrogate.pyg_dataset import SimDataset

#: each name of the API: (its module, its name there)
_API = {"SimDataset": ("surrogate.pyg_dataset", "SimDataset"), "Trajectory": ("generators.h5md", "Trajectory"),
        "example_sim": ("surrogate.pretrained", "example"),
        "load_sim": ("generators.h5md", "read"), "load_simulator": ("surrogate.api", "load_simulator"),
        "rollout": ("surrogate.api", "rollout"), "rollout_mse": ("surrogate.api", "rollout_mse"),
        "save_sim": ("generators.h5md", "write")}

__all__ = ["SimDataset", "Trajectory", "example_sim", "load_sim", "load_simulator", "rollout", "rollout_mse",
           "save_sim"]


def __getattr__(name: str):
    if name not in _API:
        raise AttributeError(f"module 'graphdem' has no attribute {name!r}")
    module, attr = _API[name]
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value                 # the next look-up finds it without this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
