"""The one-step loss of training (article 5.4.3; docs/surrogate.md, Training): a batch's samples with their random
draws (random-walk input noise, mirror, pushforward) and the mean squared error of the normalised acceleration over
their moving particles."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from surrogate import devices, distributed
from surrogate.graph import Graph, build_graph, prune_isolated, stack_graphs
from surrogate.noise import random_walk_position_noise
from surrogate.samples import Sim
from surrogate.simulator import LearnedSimulator, moving_acceleration


def mirror_x(positions: torch.Tensor, lower: torch.Tensor, upper: torch.Tensor) -> torch.Tensor:
    """Positions reflected in the vertical plane through the domain's centre, ``x -> x_lo + x_hi - x``.

    Gravity acts along the last axis, so the mirror image of a granular flow is a flow obeying the
    same laws: a valid extra training sample (``train.mirror``)."""
    out = positions.clone()
    out[..., 0] = lower[0] + upper[0] - positions[..., 0]
    return out


@dataclass
class _Sample:
    """One training sample's inputs on the model's device."""

    window: torch.Tensor            # [K, N, D] the noisy history
    following: torch.Tensor         # [B, N, D] the B positions the target accelerations lead to
    truth: torch.Tensor             # [m, B, N, D] the true frames of the m pushed steps (kinematic part used)
    types: torch.Tensor
    kinematic: torch.Tensor
    props: torch.Tensor | None

    def graph(self, window: torch.Tensor, radius: float, max_neighbours: int | None = None):
        return build_graph(window, self.types, self.kinematic, radius, self.props, max_neighbours=max_neighbours)


def _draws(simulator: LearnedSimulator, sims: list[Sim], batch: list[tuple[int, int]], noise_std: float,
           generator: torch.Generator, mirror: bool, pushforward: float, pushforward_steps: int,
           keep: range) -> list[_Sample]:
    """The random draws of a whole batch, and the inputs of the samples at positions ``keep``.

    Every sample's flip, pushforward, step count and noise are drawn in the batch's order, kept or not, so a
    process that computes a share of the batch gives each sample the draws one process gives it."""
    k, bundle = simulator.history, simulator.bundle
    n = len(batch)
    flips = torch.rand(n, generator=generator) < 0.5 if mirror else torch.zeros(n, dtype=torch.bool)
    pushed = torch.rand(n, generator=generator) < pushforward if pushforward > 0 else torch.zeros(n, dtype=torch.bool)
    # m is drawn only for multi-step pushforward, so one-step runs keep their random stream unchanged
    steps = (torch.randint(1, pushforward_steps + 1, (n,), generator=generator) if pushforward_steps > 1
             else torch.ones(n, dtype=torch.long))
    device = simulator.lower.device
    kept = []
    for i, ((s, t), flip, push, m) in enumerate(zip(batch, flips.tolist(), pushed.tolist(), steps.tolist(),
                                                     strict=True)):
        sim = sims[s]
        noise = random_walk_position_noise(k, sim.position.shape[1], sim.position.shape[2], noise_std, ~sim.kinematic,
                                           generator)
        if i not in keep:
            continue
        m = min(m, (t - k + 1) // bundle) if push else 0       # pushed steps need frames before the window
        frames = sim.position[t - k + 1 - m * bundle:t + 1 + bundle]
        if flip:
            frames = mirror_x(frames, simulator.lower.to(frames.device), simulator.upper.to(frames.device))
        # the target keeps the true next positions relative to the noisy last one: the model learns to
        # correct the velocity noise, not to reproduce it (Sanchez-Gonzalez et al. 2020)
        following = frames[-bundle:] + noise[-1] if m == 0 else frames[-bundle:]
        pushed_truth = frames[k:k + m * bundle].reshape(m, bundle, *frames.shape[1:])
        kept.append(_Sample((frames[:k] + noise).to(device), following.to(device), pushed_truth.to(device),
                            sim.types.to(device), sim.kinematic.to(device),
                            None if sim.props is None else sim.props.to(device)))
    return kept


def type_weights(types: torch.Tensor, balance: float) -> torch.Tensor:
    """Loss weights of one sample's moving particles (``types``, their type ids), by ``train.type_balance`` = b.

    A particle of a type with n moving particles in the sample weighs n^-b, scaled so that the weights average 1
    over the sample: b = 0 weighs every particle alike (the plain mean), b = 1 gives every type the same total
    weight whatever its count. Between them, a type of few particles (the meteorite's 19 discs against 666 of
    ground) counts for more than its share without every particle of it counting as much as a whole type."""
    if not 0 <= balance <= 1:
        raise ValueError(f"train.type_balance = {balance!r}: allowed a number in [0, 1] (0: every particle alike)")
    if balance == 0 or types.numel() == 0:
        return torch.ones(types.shape, dtype=torch.float32, device=types.device)
    counts = torch.bincount(types).to(torch.float64)
    weights = counts[types] ** -balance
    return (weights * (types.numel() / weights.sum())).to(torch.float32)


def batch_loss(simulator: LearnedSimulator, sims: list[Sim], batch: list[tuple[int, int]], noise_std: float,
               generator: torch.Generator, mirror: bool = False, pushforward: float = 0.0,
               pushforward_steps: int = 1, *, world: distributed.World | None = None,
               model: torch.nn.Module | None = None, precision: str = "float32",
               counts: dict | None = None, pushforward_gradient: bool = False,
               type_balance: float = 0.0) -> torch.Tensor:
    """Mean squared error of the normalised acceleration over the moving particles of a batch.

    With ``mirror``, each sample is reflected in x (window and target together) with probability 1/2.
    With ``pushforward`` = p, each sample that has a frame before its window is, with probability p,
    a pushforward sample (Brandstetter et al. 2022): its history ends in the model's own predictions,
    made without gradient from the (noisy) window m frames earlier, and the target is the true next
    frame. m is drawn uniformly from 1 .. ``pushforward_steps`` (at most the frames there are before
    the window). The model so learns to correct the errors it makes itself in a rollout, at the cost
    of m extra forward passes per such sample.

    A model that predicts B frames per call (``model.bundle`` = B, temporal bundling) is trained on the
    accelerations of the next B frames, all B in the loss; its pushed steps are calls of B frames each, so a
    pushed sample's history ends in m B predicted frames (m at most the whole calls there are frames for).

    With ``pushforward_gradient`` the pushed steps keep their gradient: a multi-step loss. Each pushed step's
    acceleration error, taken against the true next frame (the target rule of the last step, so each term is
    that step's position error in normalised units), joins the loss, and the gradient of every later term
    flows back through the positions the earlier steps predicted (backpropagation through the rollout).
    The loss is the mean over all of a batch's step terms. Each pushed step then costs a backward pass too.
    One process only (a DistributedDataParallel model takes one forward pass per backward pass).

    With a multi-process ``world``, this process computes its share of the samples
    (:func:`surrogate.distributed.share`) and returns their squared errors summed, divided by the
    whole batch's count of moving particle components, times the number of processes: the processes'
    mean of this loss (and of its gradient, what DDP averages) is the one-process loss of the batch.
    A process with no sample in a short batch computes the first sample with weight 0, so that every
    process takes part in the gradient's exchange. ``model`` computes the prediction that carries the
    gradient (the DDP wrapper; default ``simulator``); ``precision`` = ``bfloat16`` runs the forward
    passes under bfloat16 autocast (:func:`surrogate.devices.autocast`).

    With ``type_balance`` = b > 0 each moving particle's squared error is weighted by :func:`type_weights` of its
    sample (mean weight 1 per sample, so the loss keeps its scale and the multi-process rule above holds); the
    multi-step loss (``pushforward_gradient``) takes no weights and refuses it.

    Every graph keeps each receiver's ``simulator.max_neighbours`` nearest senders where that cap is set;
    ``counts`` (a dict with ``capped``, ``dropped`` and ``edges``), when given, gets the receivers capped,
    the edges dropped and the edges before the cap of the graphs the loss is computed on (this process's
    share) added.
    """
    world = world or distributed.World()
    model = model or simulator
    _refuse_multi_step(pushforward_gradient, type_balance, world)
    keep = distributed.share(len(batch), world)
    weight = 1.0
    if not keep:
        keep, weight = range(1), 0.0
    drawn = _draws(simulator, sims, batch, noise_std, generator, mirror, pushforward, pushforward_steps, keep)
    with devices.autocast(simulator.lower.device, precision):
        windows, step_errors = _pushed_steps(simulator, model, drawn, pushforward_gradient)
        # a weight-0 stand-in sample is not training data: its graph is not counted
        prediction, targets, rows = _prediction(simulator, model, drawn, windows, counts if weight > 0 else None)
    squared = (prediction.float() - torch.cat(targets)[rows]) ** 2
    if type_balance:                                   # the stacked graph's moving particles, sample by sample
        squared = squared * torch.cat([type_weights(sample.types[~sample.kinematic], type_balance)
                                       for sample in drawn]).unsqueeze(1)
    if step_errors:
        return torch.cat([*step_errors, squared]).mean()
    if not world.distributed:
        return squared.mean()
    components = sum(int((~sims[s].kinematic).sum()) for s, _ in batch) * squared.shape[-1]
    return squared.sum() * (weight * world.size / components)


def _refuse_multi_step(pushforward_gradient: bool, type_balance: float, world: distributed.World) -> None:
    """The settings the multi-step loss (``pushforward_gradient``) does not run with, refused by key."""
    if pushforward_gradient and world.distributed:
        raise ValueError("train.pushforward_gradient: the multi-step loss runs in one training process, "
                         f"got {world.size} (set launch.processes: 1 or pushforward_gradient: false)")
    if pushforward_gradient and type_balance:
        raise ValueError(f"train.type_balance = {type_balance!r} with train.pushforward_gradient: the multi-step loss "
                         f"takes no type weights (set type_balance: 0 or pushforward_gradient: false)")


def _pushed_steps(simulator: LearnedSimulator, model: torch.nn.Module, drawn: list[_Sample],
                  pushforward_gradient: bool) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
    """The pushforward steps of the samples ``drawn``: each sample's history after its pushed steps (its window
    where it has none), and with ``pushforward_gradient`` the steps' squared errors, with their gradient."""
    windows = [sample.window for sample in drawn]
    radius, cap = simulator.radius, simulator.max_neighbours
    step_errors = []
    for j in range(max(len(sample.truth) for sample in drawn)):
        which = [i for i, sample in enumerate(drawn) if len(sample.truth) > j]
        earlier = stack_graphs([drawn[i].graph(windows[i], radius, cap) for i in which])
        truth = torch.cat([drawn[i].truth[j] for i in which], dim=1)     # [B, N, D]
        if pushforward_gradient:
            predicted, squared = _graded_step(simulator, model, earlier, truth)
            step_errors.append(squared)
        else:
            with torch.no_grad():
                predicted = simulator.step(earlier, truth)
        sizes = [windows[i].shape[1] for i in which]
        for i, frames in zip(which, predicted.split(sizes, dim=1), strict=True):
            windows[i] = torch.cat([windows[i], frames])[-len(windows[i]):]
    return windows, step_errors


def _prediction(simulator: LearnedSimulator, model: torch.nn.Module, drawn: list[_Sample],
                windows: list[torch.Tensor], counts: dict | None
                ) -> tuple[torch.Tensor, list[torch.Tensor], torch.Tensor]:
    """``model``'s normalised accelerations of the moving particles from the samples' histories ``windows`` (their
    graphs stacked), the samples' targets, and the rows of the targets' concatenation that the predictions are of;
    the neighbour cap's cuts added to ``counts`` (when given)."""
    radius, cap = simulator.radius, simulator.max_neighbours
    graphs = [sample.graph(window, radius, cap) for window, sample in zip(windows, drawn, strict=True)]
    targets = [simulator.target(window, sample.following) for window, sample in zip(windows, drawn, strict=True)]
    stacked = stack_graphs(graphs)
    if counts is not None:
        counts["capped"] += stacked.capped_receivers
        counts["dropped"] += stacked.dropped_edges
        counts["edges"] += stacked.edge_index.shape[1] + stacked.dropped_edges
    # isolated wall particles cannot change a prediction: left out (exact), and only moving particles decoded
    graph, index = prune_isolated(stacked)
    moving = (~graph.kinematic).nonzero().squeeze(1)
    return model(graph, decode=moving), targets, index[moving]


def _graded_step(simulator: LearnedSimulator, model: torch.nn.Module, graph: Graph, truth: torch.Tensor
                 ) -> tuple[torch.Tensor, torch.Tensor]:
    """One pushed step with its gradient: the next B positions ``[B, N, D]`` (``truth``'s for the unpredicted
    particles) and the squared error of the moving particles' normalised accelerations against those reaching
    ``truth``."""
    where, window, acceleration = moving_acceleration(model, graph)
    squared = (acceleration.float() - simulator.target(window, truth[:, where])) ** 2
    frames = simulator.integrate(window, acceleration).to(truth.dtype)
    nxt = truth.transpose(0, 1).index_put((where,), frames.transpose(0, 1)).transpose(0, 1)
    return nxt, squared
