"""The learned simulator: Graph-DEM wrapped in the data conventions of article section 3.

It turns a window of K positions into model inputs (normalised velocities, type embedding ids,
boundary distances, the radius graph), turns the model's normalised acceleration back into
physical units and advances positions with eq. (1):

.. math::
    \\dot p^{t+1} = \\dot p^{t} + \\ddot p^{t+1}, \\qquad p^{t+1} = p^{t} + \\dot p^{t+1}

With the model config's ``bundle`` = B (temporal bundling, Brandstetter et al. 2022; absent: 1, the
article's one frame per call) the generator predicts the accelerations of the next B frames at once,
:math:`\\ddot p^{t+1}, \\dots, \\ddot p^{t+B}`, from the one graph of frame t, and eq. (1) is applied B
times in turn: a rollout of T frames takes T / B network calls. Every frame-producing method therefore
works on a bundle axis: :meth:`LearnedSimulator.integrate` and :meth:`LearnedSimulator.step` return
``[B, N, D]``, and :meth:`LearnedSimulator.target` takes the B following frames.

Kinematic particles are never predicted: :meth:`step` returns their next positions unchanged from
whatever the caller supplies (the data), and the graph has no kinematic-kinematic edges.

With the model config's ``max_neighbours`` = N, every graph the simulator is given (training, validation,
rollout) keeps each receiver's N nearest senders (:func:`surrogate.graph.cap_neighbours`); the graph
records the receivers capped and the edges dropped. The graph itself (:class:`surrogate.graph.Graph`, built by
:func:`surrogate.graph.build_graph`) is surrogate/graph.py's.
"""

from __future__ import annotations

import torch
from torch import nn

from surrogate.graph import Graph, prune_isolated
from surrogate.model.constructor import boundary_features, check_edge_features
from surrogate.model.graphdem import GraphDEM
from surrogate.neighbours import check_cap


class LearnedSimulator(nn.Module):
    """Graph-DEM plus normalisation statistics, boundaries and radius from the dataset metadata."""

    def __init__(self, stats: dict, model_cfg: dict):
        super().__init__()
        self.stats = dict(stats)                 # what it was trained with (a checkpoint stores both)
        self.model_config = dict(model_cfg)
        self.dim = int(stats["dim"])
        self.history = int(model_cfg["history"])
        self.radius = float(stats["connectivity_radius"])
        # senders kept per receiver (null: every one within R); absent in checkpoints from before the key
        self.max_neighbours = check_cap(model_cfg.get("max_neighbours"))
        self.property_names = list(model_cfg.get("properties") or [])
        # frames predicted per network call (temporal bundling); absent (and in older checkpoints): 1
        self.bundle = check_bundle(model_cfg.get("bundle", 1))
        # optional edge inputs beyond eq. (7); absent (and in checkpoints from before the key): none
        self.edge_features = tuple(model_cfg.get("edge_features") or ())
        check_edge_features(self.edge_features)
        if "gap" in self.edge_features and "radius" not in self.property_names:
            raise ValueError(f"model.edge_features: gap needs the particle radius, so model.properties must list "
                             f"radius (it lists {self.property_names})")
        self.model = GraphDEM(
            dim=self.dim, history=self.history, n_types=int(stats["n_types"]),
            n_props=len(self.property_names), latent=int(model_cfg["latent"]), hidden=int(model_cfg["hidden"]),
            message_passing=int(model_cfg["message_passing"]), embed=int(model_cfg["embed"]),
            layers=int(model_cfg["mlp_layers"]), edge_features=self.edge_features, bundle=self.bundle)
        bounds = torch.tensor(stats["bounds"], dtype=torch.float32)
        self.register_buffer("lower", bounds[:, 0].clone())
        self.register_buffer("upper", bounds[:, 1].clone())
        for name in ("velocity_mean", "velocity_std", "acceleration_mean", "acceleration_std"):
            self.register_buffer(name, torch.tensor(stats[name], dtype=torch.float32))

    def velocities(self, window: torch.Tensor) -> torch.Tensor:
        """Normalised K-1 velocities ``[N, K-1, D]`` of a window ``[K, N, D]`` (eq. 1)."""
        vel = (window[1:] - window[:-1]).transpose(0, 1)
        return (vel - self.velocity_mean) / self.velocity_std

    def forward(self, graph: Graph, decode: torch.Tensor | None = None) -> torch.Tensor:
        """Normalised accelerations ``[N, B D]`` of the next B frames (of the nodes ``decode`` only, when given)."""
        if graph.window.shape[0] != self.history:
            raise ValueError(f"the model takes a history of K = {self.history} frames, got {graph.window.shape[0]}")
        last = graph.window[-1]
        boundary = boundary_features(last, self.lower, self.upper, self.radius)
        velocity = last - graph.window[-2] if self.edge_features else None
        radii = self.radii(graph.props) if "gap" in self.edge_features else None
        return self.model(self.velocities(graph.window), graph.types, boundary, last, graph.edge_index,
                          self.radius, graph.props, decode, velocity, radii)

    def radii(self, props: torch.Tensor) -> torch.Tensor:
        """[N] particle radii (m) recovered from the normalised node property ``radius``."""
        s = self.stats["property_stats"]["radius"]
        values = props[:, self.property_names.index("radius")] * s["std"] + s["mean"]
        return torch.exp(values) if s.get("log") else values

    def target(self, window: torch.Tensor, following: torch.Tensor) -> torch.Tensor:
        """Normalised accelerations ``[N, B D]`` that take ``window`` through the B frames ``following``
        ``[B, N, D]`` (``[N, D]`` is one frame, for B = 1): frame b's acceleration in columns ``b D .. (b+1) D``."""
        frames = following.unsqueeze(0) if following.dim() == window.dim() - 1 else following
        if frames.shape[0] != self.bundle:
            raise ValueError(f"the model predicts {self.bundle} frame(s) per call (model.bundle), "
                             f"got {frames.shape[0]} target frame(s)")
        path = torch.cat([window[-2:], frames])
        acc = path[2:] - 2 * path[1:-1] + path[:-2]                       # [B, N, D]
        acc = (acc - self.acceleration_mean) / self.acceleration_std
        return acc.transpose(0, 1).flatten(1)

    @property
    def n_models(self) -> int:
        """Models whose accelerations a step averages: one (an :class:`surrogate.ensemble.Ensemble` has several)."""
        return 1

    def denormalise(self, acceleration: torch.Tensor) -> torch.Tensor:
        """The physical accelerations (m per frame^2) ``[N, B D]`` of normalised ones (every frame of a bundle
        with the same statistics)."""
        return acceleration * self.acceleration_std.repeat(self.bundle) + self.acceleration_mean.repeat(self.bundle)

    def integrate(self, window: torch.Tensor, acceleration: torch.Tensor) -> torch.Tensor:
        """The next B frames ``[B, N, D]`` from a normalised acceleration ``[N, B D]`` (eq. 1, B times)."""
        return advance(window, self.denormalise(acceleration))

    def step(self, graph: Graph, kinematic_next: torch.Tensor) -> torch.Tensor:
        """Positions of the next B frames ``[B, N, D]``: predicted for moving particles, ``kinematic_next``
        (``[B, N, D]``, or ``[N, D]`` for B = 1) for the rest.

        Isolated unpredicted particles are left out of the computation (:func:`prune_isolated`,
        exact) and only the moving particles are decoded."""
        return next_frame(self, graph, kinematic_next)


def check_bundle(bundle) -> int:
    """``model.bundle`` as an int >= 1, or a ValueError naming the key and what is allowed."""
    if isinstance(bundle, bool) or not isinstance(bundle, int) or bundle < 1:
        raise ValueError(f"model.bundle = {bundle!r}: allowed an integer >= 1 (frames predicted per network call)")
    return bundle


def advance(window: torch.Tensor, acceleration: torch.Tensor) -> torch.Tensor:
    """The next B frames ``[B, N, D]`` from a window and physical accelerations ``[N, B D]`` (eq. 1 applied B
    times: p <- p + (p - p_prev) + a_b)."""
    previous, current = window[-2], window[-1]
    frames = []
    for a in acceleration.split(window.shape[-1], dim=-1):
        nxt = current + (current - previous) + a
        frames.append(nxt)
        previous, current = current, nxt
    return torch.stack(frames)


def moving_acceleration(model: nn.Module, graph: Graph) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``model``'s prediction for the moving particles of the pruned graph (:func:`surrogate.graph.prune_isolated`):
    their indices in ``graph``, their window ``[K, M, D]`` and their normalised accelerations ``[M, B D]``."""
    reduced, index = prune_isolated(graph)
    moving = (~reduced.kinematic).nonzero().squeeze(1)
    return index[moving], reduced.window[:, moving], model(reduced, decode=moving)


def next_frame(model: nn.Module, graph: Graph, kinematic_next: torch.Tensor) -> torch.Tensor:
    """:meth:`LearnedSimulator.step` of ``model``, a simulator or an ensemble: its ``integrate`` applied to its
    prediction for the moving particles of the pruned graph, ``[B, N, D]``; ``kinematic_next`` (``[B, N, D]``,
    or ``[N, D]`` for one frame) for the rest."""
    where, window, acceleration = moving_acceleration(model, graph)
    rest = kinematic_next.unsqueeze(0) if kinematic_next.dim() == graph.window.dim() - 1 else kinematic_next
    nxt = rest.clone()
    nxt[:, where] = model.integrate(window, acceleration).to(nxt.dtype)
    return nxt
