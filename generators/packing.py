"""Settled packings shared by sims: the content key of a packing's parameters (Scene.packing_params)."""

from __future__ import annotations

import hashlib
import json


def packing_key(params: dict) -> str:
    """A short content key: identical parameters share one settled packing."""
    digest = hashlib.sha256(json.dumps(params, sort_keys=True).encode()).hexdigest()[:10]
    return f"p{params.get('packing_index', 0)}-{digest}"
