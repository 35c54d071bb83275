"""Settled packings shared by sims: which parameters make one, and its content key."""

from __future__ import annotations

import hashlib
import json


def packing_params(cfg: dict, keys: tuple[str, ...], index: int | None = None, **fixed) -> dict:
    """The parameters ``keys`` of ``cfg`` that shape a settled packing, its seed, ``index`` (when the
    scene has several packings) and any ``fixed`` value (e.g. the modulus a packing is settled at)."""
    params = {k: cfg[k] for k in keys}
    params.update(fixed)
    params["seed"] = int(cfg["seed"])
    if index is not None:
        params["packing_index"] = int(index)
    return params


def packing_key(params: dict) -> str:
    """A short content key: identical parameters share one settled packing."""
    digest = hashlib.sha256(json.dumps(params, sort_keys=True).encode()).hexdigest()[:10]
    return f"p{params.get('packing_index', 0)}-{digest}"
