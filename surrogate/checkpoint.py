"""Checkpoints: model weights plus the config and dataset statistics they were trained with.

Everything but tensors is stored as JSON text, so checkpoints load with
``torch.load(weights_only=True)``: a checkpoint file cannot execute code when it is read.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import torch

from generators.atomic import atomic_path
from surrogate.errors import CheckpointError
from surrogate.simulator import LearnedSimulator

__all__ = ["CheckpointError", "digest", "load", "save", "simulator_from"]


def save(path: Path, payload: dict) -> None:
    """Write ``payload`` atomically; dict values under ``json`` are serialised as JSON text."""
    data = dict(payload)
    data["json"] = json.dumps(payload.get("json", {}), sort_keys=True)
    with atomic_path(Path(path)) as tmp:
        torch.save(data, tmp)


def load(path: str | Path) -> dict:
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{path}: no such checkpoint")
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:   # noqa: BLE001 - torch raises many types for a bad file
        raise CheckpointError(f"{path}: not a loadable Graph-DEM checkpoint (only tensors and plain "
                              f"data are accepted): {exc}") from exc
    if not isinstance(data, dict) or "json" not in data or "model" not in data:
        raise CheckpointError(f"{path}: not a Graph-DEM checkpoint (missing 'model' or 'json')")
    try:
        data["json"] = json.loads(data["json"])
    except (TypeError, json.JSONDecodeError) as exc:
        raise CheckpointError(f"{path}: its 'json' entry is not JSON text: {exc}") from exc
    meta = data["json"]
    if not (isinstance(meta, dict) and all(isinstance(meta.get(k), dict) for k in ("stats", "model"))):
        raise CheckpointError(f"{path}: its metadata lacks the 'stats' and 'model' of a Graph-DEM checkpoint")
    if not isinstance(data["model"], dict):
        raise CheckpointError(f"{path}: its 'model' entry is not a state dict of tensors")
    return data


def simulator_from(path: str | Path) -> tuple[LearnedSimulator, dict]:
    """The trained simulator of a checkpoint, in eval mode, and the checkpoint's JSON metadata."""
    data = load(path)
    meta = data["json"]
    try:
        simulator = LearnedSimulator(meta["stats"], meta["model"])
        simulator.load_state_dict(data["model"])
    except (KeyError, RuntimeError, TypeError, ValueError, AttributeError) as exc:
        raise CheckpointError(f"{path}: weights do not fit the model it describes: {exc}") from exc
    return simulator.eval(), meta


def digest(path: str | Path) -> str:
    """Short SHA-256 of a file (names a checkpoint in every metrics file)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()[:12]
