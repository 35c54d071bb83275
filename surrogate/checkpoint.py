"""Checkpoints: model weights plus the config and dataset statistics they were trained with.

Everything but tensors is stored as JSON text, so checkpoints load with
``torch.load(weights_only=True)``: a checkpoint file cannot execute code when it is read.
Tensors are stored from the CPU whatever device trained them, and load onto any device
(``map_location``; :func:`simulator_from` takes the ``device`` setting of :mod:`surrogate.devices`).

Reading one costs at most about its own size, whatever it claims: it must be torch.save's zip archive with every
record stored uncompressed (no deflated record inflates to gigabytes), every tensor it holds must fit in the bytes
stored (no view that repeats a few bytes over a huge shape), its model sizes must lie in the config schema's ranges
(``#/$defs/model``), and the model it describes must have exactly the shapes of the weights stored, checked on the
meta device before any model is built.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import torch

from generators import config
from generators.atomic import atomic_path
from generators.errors import ConfigError
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
    memory) and its JSON metadata, checked to be a Graph-DEM checkpoint's, its model sizes within the config
    schema's ranges."""
    data = read(path, map_location)
    meta = data["json"]
    if not (isinstance(meta, dict) and all(isinstance(meta.get(k), dict) for k in ("stats", "model"))):
        raise CheckpointError(f"{path}: its metadata lacks the 'stats' and 'model' of a Graph-DEM checkpoint")
    if not isinstance(data["model"], dict):
        raise CheckpointError(f"{path}: its 'model' entry is not a state dict of tensors")
    _check_model_sizes(meta["model"], path)
    return data


def _check_model_sizes(model: dict, path: str | Path) -> None:
    """Refuse model settings outside the ranges the config schema allows (``#/$defs/model``: latent, hidden,
    message passing, history, embedding, layers, bundle...), each checked on its own: a checkpoint from before a
    key was added lacks it."""
    allowed = config.schema()["$defs"]["model"]["properties"]
    for key in sorted(set(model) & set(allowed)):
        try:
            config.validate_part(model[key], f"#/$defs/model/properties/{key}", f"model.{key}")
        except ConfigError as exc:
            detail = " ".join(str(exc).replace("invalid configuration:", "").split())
            raise CheckpointError(f"{path}: its model metadata is outside the config schema's range: {detail}") from exc


def _check_records(path: Path) -> int:
    """The bytes the archive's records hold; refuse a file that is not torch.save's zip archive (the legacy format
    reads sizes it declares before checking them) or that has a compressed record (it could inflate to any size)."""
    with path.open("rb") as fh:
        if fh.read(4) != b"PK\x03\x04":
            raise CheckpointError(f"{path}: not a loadable Graph-DEM checkpoint: not the zip archive torch.save "
                                  f"writes (the only format read)")
    try:
        with zipfile.ZipFile(path) as archive:
            records = archive.infolist()
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise CheckpointError(f"{path}: not a loadable Graph-DEM checkpoint (a damaged zip archive): {exc}") from exc
    size = path.stat().st_size
    for record in records:
        if record.compress_type != zipfile.ZIP_STORED or record.compress_size != record.file_size:
            raise CheckpointError(f"{path}: record {record.filename} is compressed (zip method "
                                  f"{record.compress_type}); torch.save stores its records uncompressed, so only "
                                  f"those are read")
        if record.file_size > size:
            raise CheckpointError(f"{path}: record {record.filename} claims {record.file_size} bytes, more than the "
                                  f"file's {size}")
    return sum(record.file_size for record in records)


def _check_tensor_bytes(data: Any, stored: int, path: Path) -> None:
    """Refuse a checkpoint whose tensors, counted whole, hold more bytes than its records store (a view whose
    shape repeats a few stored bytes: materialising it would allocate the whole shape)."""
    total, todo = 0, [data]
    while todo:
        value = todo.pop()
        if isinstance(value, torch.Tensor):
            total += value.numel() * value.element_size()
            if total > stored:
                raise CheckpointError(f"{path}: its tensors hold more than the {stored} bytes it stores (a tensor of "
                                      f"shape {tuple(value.shape)} repeats its data); refused before use")
        elif isinstance(value, dict):
            todo.extend(value.values())
        elif isinstance(value, list | tuple):
            todo.extend(value)


def _reason(exc: Exception) -> str:
    """torch.load's error on one line: the unpickler's own reason where it gives one, without the advice around it."""
    text = str(exc)
    if "WeightsUnpickler error:" in text:
        text = text.split("WeightsUnpickler error:", 1)[1].split("Check the documentation of torch.load", 1)[0]
    return " ".join(text.split())


def read(path: str | Path, map_location: str | torch.device = "cpu") -> dict:
    """A file written by :func:`save`: its tensors on ``map_location`` and its JSON metadata (``json``), read with
    ``weights_only=True`` (no code runs); any model's, not only Graph-DEM's. What it may allocate is bounded by
    its size (:func:`_check_records`, :func:`_check_tensor_bytes`) before anything but its index is read."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{path}: no such checkpoint")
    stored = _check_records(path)
    try:
        data = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as exc:   # noqa: BLE001 - torch raises many types for a bad file
        raise CheckpointError(f"{path}: not a loadable Graph-DEM checkpoint (only tensors and plain "
                              f"data are accepted): {_reason(exc)}") from exc
    if not isinstance(data, dict) or "json" not in data or "model" not in data:
        raise CheckpointError(f"{path}: not a Graph-DEM checkpoint (missing 'model' or 'json')")
    _check_tensor_bytes(data, stored, path)
    try:
        data["json"] = json.loads(data["json"])
    except (TypeError, json.JSONDecodeError, RecursionError) as exc:
        raise CheckpointError(f"{path}: its 'json' entry is not JSON text: {exc}") from exc
    return data


def _check_shapes(meta: dict, weights: dict, path: str | Path) -> None:
    """Refuse weights that do not have exactly the shapes of the model ``meta`` describes, checked on the meta
    device (no memory): the model built next is then no larger than the weights stored."""
    from surrogate.simulator import LearnedSimulator

    with torch.device("meta"):
        expected = LearnedSimulator(meta["stats"], meta["model"]).state_dict()
    missing, extra = sorted(set(expected) - set(weights)), sorted(set(weights) - set(expected))
    if missing or extra:
        raise CheckpointError(f"{path}: weights do not fit the model it describes: missing {missing[:3]}, "
                              f"unexpected {extra[:3]}")
    for name, value in expected.items():
        stored = weights[name]
        if not isinstance(stored, torch.Tensor) or tuple(stored.shape) != tuple(value.shape):
            shape = tuple(stored.shape) if isinstance(stored, torch.Tensor) else type(stored).__name__
            raise CheckpointError(f"{path}: weights do not fit the model it describes: {name} is {shape}, the "
                                  f"model's {tuple(value.shape)}")


def simulator_from(path: str | Path, device: str | torch.device = "cpu") -> tuple[LearnedSimulator, dict]:
    """The trained simulator of a checkpoint on ``device`` (a setting of :mod:`surrogate.devices`: auto, cpu,
    cuda, cuda:N), in eval mode, and the checkpoint's JSON metadata."""
    from surrogate.simulator import LearnedSimulator

    where = devices.resolve(device)
    data = load(path, map_location=where)
    meta = data["json"]
    try:
        _check_shapes(meta, data["model"], path)
        simulator = LearnedSimulator(meta["stats"], meta["model"]).to(where)
        simulator.load_state_dict(data["model"])
    except CheckpointError:
        raise
    except (KeyError, RuntimeError, TypeError, ValueError, AttributeError) as exc:
        raise CheckpointError(f"{path}: weights do not fit the model it describes: {exc}") from exc
    return simulator.eval(), meta

