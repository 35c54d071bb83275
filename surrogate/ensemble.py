"""Ensembles at inference: several trained simulators (e.g. the same scene trained with other seeds) as one.

Every step, each model predicts the acceleration of the moving particles from the same history and
the same graph, in physical units (its own normalisation undone: m per frame^2), and the mean of
these accelerations is integrated once (eq. 1). The ensemble stands wherever a simulator does
(:func:`surrogate.rollout.rollout`, :func:`surrogate.batched.rollout_batch`, the runtime switches of
:func:`surrogate.runtime.apply`): its ``forward`` returns that mean acceleration and its
``integrate`` adds it without normalising again. An ensemble of one model rolls out bit for bit as
the model alone. Its cost is the models' forward passes one after another on one graph per step:
the network time per frame grows with the number of models, the graph is built once.

The models must read the same inputs and agree on what they predict, so an ensemble refuses models
that differ in any of :data:`SHARED_MODEL` (model config) or :data:`SHARED_STATS` (dataset statistics:
the graph's radius, the frame interval that velocities are per, the box, the particle types), or in
the normalisation of a node property they read; the error names the key. Their velocity and
acceleration statistics may differ: each model normalises its own inputs and outputs.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from pathlib import Path

import torch
from torch import nn

from surrogate import checkpoint
from surrogate.graph import Graph
from surrogate.provenance import as_paths
from surrogate.simulator import LearnedSimulator, advance, next_frame

SHARED_MODEL = ("history", "max_neighbours", "properties", "bundle")
SHARED_STATS = ("dim", "connectivity_radius", "frame_interval", "bounds", "n_types", "scene", "kinematic_species",
                "velocity_unit", "acceleration_unit")


def check_compatible(members: Sequence[LearnedSimulator], names: Sequence[str]) -> None:
    """Refuse an empty ensemble, or models that differ in a shared key (module docstring), naming the key
    and the two models."""
    if not members:
        raise ValueError("an ensemble needs at least one model")
    first, first_name = members[0], names[0]
    for member, name in zip(members[1:], names[1:], strict=True):
        differ = [(f"model.{key}", first.model_config.get(key), member.model_config.get(key))
                  for key in SHARED_MODEL]
        differ += [(f"stats.{key}", first.stats.get(key), member.stats.get(key)) for key in SHARED_STATS]
        differ += [(f"stats.property_stats.{prop}", (first.stats.get("property_stats") or {}).get(prop),
                    (member.stats.get("property_stats") or {}).get(prop)) for prop in first.property_names]
        for key, want, got in differ:
            if _normal(key, want) != _normal(key, got):
                raise ValueError(f"ensemble: {name} has {key} = {got!r}, {first_name} {want!r}; the models of an "
                                 f"ensemble must share {', '.join(f'model.{k}' for k in SHARED_MODEL)}, "
                                 f"{', '.join(f'stats.{k}' for k in SHARED_STATS)} and the statistics of the "
                                 f"node properties they read")


def _normal(key: str, value):
    """A value as compared: a missing cap is no cap, a property list is compared as listed, and a missing bundle
    is one frame per call."""
    if key == "model.properties":
        return list(value or [])
    if key == "model.bundle":
        return 1 if value is None else value
    return value


class Ensemble(nn.Module):
    """Several :class:`LearnedSimulator` s that step together: the mean of their physical accelerations
    (module docstring). ``names`` label the models in errors (default: model 0, 1, ...)."""

    def __init__(self, members: Sequence[LearnedSimulator], names: Sequence[str] | None = None):
        super().__init__()
        names = [f"model {i}" for i in range(len(members))] if names is None else [str(n) for n in names]
        if len(names) != len(members):
            raise ValueError(f"an ensemble of {len(members)} models got {len(names)} names")
        check_compatible(members, names)
        self.members = nn.ModuleList(members)
        self.names = names
        first = members[0]
        self.stats, self.model_config = first.stats, first.model_config
        self.dim, self.history, self.radius = first.dim, first.history, first.radius
        self.max_neighbours, self.property_names = first.max_neighbours, first.property_names
        self.bundle = first.bundle

    @property
    def n_models(self) -> int:
        return len(self.members)

    @property
    def lower(self) -> torch.Tensor:
        """The box's lower corner (the models share it)."""
        return self.members[0].lower

    @property
    def upper(self) -> torch.Tensor:
        return self.members[0].upper

    def forward(self, graph: Graph, decode: torch.Tensor | None = None) -> torch.Tensor:
        """The models' mean physical accelerations ``[N, B D]`` (of the nodes ``decode`` only, when given): each
        model's output in its weights' dtype, denormalised, summed in model order and divided by their number."""
        total = None
        for member in self.members:
            acceleration = member.denormalise(member(graph, decode).to(member.acceleration_std.dtype))
            total = acceleration if total is None else total + acceleration
        return total / len(self.members)

    def integrate(self, window: torch.Tensor, acceleration: torch.Tensor) -> torch.Tensor:
        """The next B frames ``[B, N, D]`` from the mean physical accelerations of :meth:`forward` (eq. 1)."""
        return advance(window, acceleration)

    def step(self, graph: Graph, kinematic_next: torch.Tensor) -> torch.Tensor:
        """As :meth:`LearnedSimulator.step`, with the mean acceleration."""
        return next_frame(self, graph, kinematic_next)


def load(paths: Path | str | Sequence[Path | str], device: str | torch.device = "cpu"
         ) -> tuple[LearnedSimulator | Ensemble, list[dict]]:
    """The simulator of one checkpoint, or the :class:`Ensemble` of several (in the order given), in eval
    mode on ``device``, and each checkpoint's JSON metadata."""
    paths = as_paths(paths)
    loaded = [checkpoint.simulator_from(path, device) for path in paths]
    metas = [meta for _, meta in loaded]
    if len(loaded) == 1:
        return loaded[0][0], metas
    return Ensemble([simulator for simulator, _ in loaded], [str(p) for p in paths]).eval(), metas


def config_digest(metas: list[dict]) -> str:
    """Short SHA-256 of the model, train and stats sections of the checkpoints' metadata (one: of its own)."""
    sections = [{k: meta[k] for k in ("model", "train", "stats")} for meta in metas]
    text = json.dumps(sections[0] if len(sections) == 1 else sections, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:12]
