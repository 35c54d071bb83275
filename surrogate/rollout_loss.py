"""The loss of rollout fine-tuning (``train.finetune``): a batch of training rollouts with the gradient through them.

One-step training (:func:`surrogate.train.batch_loss`) fits the acceleration of the next frame; the evaluation
scores the position error of a whole rollout, which a model trained frame by frame never sees. Fine-tuning a
trained model on that error itself, backpropagated through the autoregressive steps, is how weather models close
the same gap (GraphCast, Lam et al., Science 2023: 1-step training, then autoregressive fine-tuning on rollouts of
up to 12 steps). For every sim of a batch, from its first K frames (the model's history, as the K = K protocol
gives them; with ``frames`` set, from a start drawn at random so that ``frames`` frames follow) the model predicts
the next ``frames`` frames in turn, each from its own previous output, and the loss is their rollout MSE:

.. math::
    L = \\frac{1}{\\sum_d \\sigma_{a,d}^2} \\cdot \\frac{1}{\\sum_s T_s M_s}
        \\sum_s \\sum_{t} \\sum_{i \\in \\text{moving}} \\lVert \\hat p_i^t - p_i^t \\rVert^2

(the rollout MSE of docs/surrogate.md, over the batch's predicted particle-frames, divided by the summed per-axis
variance of the train split's accelerations so that it is a number without units). The radius graph of each step
is built on the predicted positions without gradient (which pairs are neighbours is not differentiable); every
edge and node input keeps the gradient of the positions it is made of. Kinematic particles take the data's
positions. The sims of a batch step together on the disjoint union of their graphs, as batched rollouts do.
"""

from __future__ import annotations

import torch

from surrogate.graph import Graph, build_graph, stack_graphs
from surrogate.rollout import kinematic_frames
from surrogate.samples import Sim, to_device
from surrogate.simulator import LearnedSimulator


def rollout_starts(sims: list[Sim], history: int, frames: int | None, generator: torch.Generator) -> list[int]:
    """Each sim's first given frame: 0 without ``frames`` (the whole sim is rolled out), else drawn uniformly
    from the starts that leave ``history`` given and ``frames`` predicted frames (0 where the sim has no more)."""
    starts = []
    for sim in sims:
        latest = sim.n_frames - history - (frames or sim.n_frames)
        if frames is not None and frames < 1:
            raise ValueError(f"train.finetune.frames = {frames}: allowed an integer >= 1 or null (the whole sim)")
        starts.append(int(torch.randint(0, latest + 1, (1,), generator=generator)) if latest > 0 else 0)
    return starts


def rollout_loss(simulator: LearnedSimulator, sims: list[Sim], frames: int | None,
                 generator: torch.Generator) -> torch.Tensor:
    """The normalised rollout MSE of the batch ``sims`` (module docstring), with the gradient through every step.

    ``frames``: predicted frames per rollout (None: every frame after the given ones)."""
    k, bundle = simulator.history, simulator.bundle
    starts = rollout_starts(sims, k, frames, generator)
    sims = [to_device(sim, simulator.lower.device) for sim in sims]
    windows = [sim.position[s:s + k] for sim, s in zip(sims, starts, strict=True)]
    ends = [min(sim.n_frames, s + k + (frames or sim.n_frames)) for sim, s in zip(sims, starts, strict=True)]
    sizes = [sim.position.shape[1] for sim in sims]
    squared, counted = [], 0
    for step in range(0, max(e - s - k for s, e in zip(starts, ends, strict=True)), bundle):
        active = [i for i in range(len(sims)) if starts[i] + k + step < ends[i]]
        graphs = []
        for i in active:
            sim = sims[i]
            edges = build_graph(windows[i].detach(), sim.types, sim.kinematic, simulator.radius, sim.props,
                                max_neighbours=simulator.max_neighbours)
            graphs.append(Graph(windows[i], edges.types, edges.kinematic, edges.edge_index, edges.props))
        t = [starts[i] + k + step for i in active]
        rest = torch.cat([kinematic_frames(sims[i], t_i, bundle, windows[i].dtype) for i, t_i in zip(active, t,
                                                                                                   strict=True)], 1)
        predicted = simulator.step(stack_graphs(graphs), rest)
        for i, t_i, frames_i in zip(active, t, predicted.split([sizes[i] for i in active], dim=1), strict=True):
            keep = min(bundle, ends[i] - t_i)
            moving = ~sims[i].kinematic
            truth = sims[i].position[t_i:t_i + keep]
            squared.append(((frames_i[:keep, moving] - truth[:, moving]) ** 2).sum(-1).flatten())
            counted += keep * int(moving.sum())
            windows[i] = torch.cat([windows[i], frames_i[:keep]])[-k:]
    variance = float((simulator.acceleration_std.double() ** 2).sum())
    return torch.cat(squared).sum() / (max(counted, 1) * variance)

