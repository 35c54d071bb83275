"""Checkpoints: model weights plus the config and dataset statistics they were trained with.

Everything but tensors is stored as JSON text, so checkpoints load with
``torch.load(weights_only=True)``: a checkpoint file cannot execute code when it is read.
Tensors are stored from the CPU whatever device trained them, and load onto any device
(``map_location``; :func:`simulator_from` takes the ``device`` setting of :mod:`surrogate.devices`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import torch

from generators.atomic import atomic_path
from surrogate import devices
from surrogate.errors import CheckpointError
from surrogate.provenance import file_digest as digest

if TYPE_CHECKING:  # the model (and torch_geometric, ~4 s to import) only where a simulator is built
    from surrogate.simulator import LearnedSimulator

__all__ = ["CheckpointError", "digest", "load", "save", "simulator_from"]


def _on_cpu(value: Any) -> Any:
    """``value`` with every tensor in it (through dicts, lists and tuples) copied to the CPU."""
    if isinstance(value, torch.Tensor):
        return value.detach().cpu()
    if isinstance(value, dict):           # a state dict keeps its type and its modules' version metadata
        out = type(value)((k, _on_cpu(v)) for k, v in value.items())
        if hasattr(value, "_metadata"):
            out._metadata = value._metadata
        return out
    if isinstance(value, list | tuple):
        return type(value)(_on_cpu(v) for v in value)
    return value


def save(path: Path, payload: dict) -> None:
    """Write ``payload`` atomically, its tensors from the CPU; dict values under ``json`` are serialised as
    JSON text."""
    data = _on_cpu({k: v for k, v in payload.items() if k != "json"})
    data["json"] = json.dumps(payload.get("json", {}), sort_keys=True)
    with atomic_path(Path(path)) as tmp:
        torch.save(data, tmp)


def load(path: str | Path, map_location: str | torch.device = "cpu") -> dict:
    """The checkpoint's tensors on ``map_location`` (``meta``: shapes and dtypes only, no data read into
    memory) and its JSON metadata, checked to be a Graph-DEM checkpoint's."""
    data = read(path, map_location)
    meta = data["json"]
    if not (isinstance(meta, dict) and all(isinstance(meta.get(k), dict) for k in ("stats", "model"))):
        raise CheckpointError(f"{path}: its metadata lacks the 'stats' and 'model' of a Graph-DEM checkpoint")
    if not isinstance(data["model"], dict):
        raise CheckpointError(f"{path}: its 'model' entry is not a state dict of tensors")
    return data


def read(path: str | Path, map_location: str | torch.device = "cpu") -> dict:
    """A file written by :func:`save`: its tensors on ``map_location`` and its JSON metadata (``json``), read with
    ``weights_only=True`` (no code runs); any model's, not only Graph-DEM's."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{path}: no such checkpoint")
    try:
        data = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as exc:   # noqa: BLE001 - torch raises many types for a bad file
        raise CheckpointError(f"{path}: not a loadable Graph-DEM checkpoint (only tensors and plain "
                              f"data are accepted): {exc}") from exc
    if not isinstance(data, dict) or "json" not in data or "model" not in data:
        raise CheckpointError(f"{path}: not a Graph-DEM checkpoint (missing 'model' or 'json')")
    try:
        data["json"] = json.loads(data["json"])
    except (TypeError, json.JSONDecodeError) as exc:
        raise CheckpointError(f"{path}: its 'json' entry is not JSON text: {exc}") from exc
    return data


def simulator_from(path: str | Path, device: str | torch.device = "cpu") -> tuple[LearnedSimulator, dict]:
    """The trained simulator of a checkpoint on ``device`` (a setting of :mod:`surrogate.devices`: auto, cpu,
    cuda, cuda:N), in eval mode, and the checkpoint's JSON metadata."""
    from surrogate.simulator import LearnedSimulator

    where = devices.resolve(device)
    data = load(path, map_location=where)
    meta = data["json"]
    try:
        simulator = LearnedSimulator(meta["stats"], meta["model"]).to(where)
        simulator.load_state_dict(data["model"])
    except (KeyError, RuntimeError, TypeError, ValueError, AttributeError) as exc:
        raise CheckpointError(f"{path}: weights do not fit the model it describes: {exc}") from exc
    return simulator.eval(), meta

