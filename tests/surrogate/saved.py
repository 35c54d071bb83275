"""An untrained Graph-DEM saved as a checkpoint beside the small synthetic dataset (tests/surrogate/synthetic.py),
for the tests of what reads a checkpoint: the commands, the API."""

from __future__ import annotations

from pathlib import Path

import torch

from surrogate import checkpoint
from surrogate.simulator import LearnedSimulator

from . import synthetic


def untrained(root: Path) -> dict:
    """synthetic.build(root) and ``checkpoint``: the path of a freshly initialised (seed 0) model of its stats,
    saved as train saves best.pt; ``simulator``: that model, in eval mode."""
    data = synthetic.build(Path(root))
    torch.manual_seed(0)
    simulator = LearnedSimulator(data["stats"], synthetic.MODEL).eval()
    path = Path(root) / "best.pt"
    checkpoint.save(path, {"model": simulator.state_dict(), "json": {"stats": data["stats"],
                                                                      "model": synthetic.MODEL}})
    return {**data, "checkpoint": path, "simulator": simulator}
