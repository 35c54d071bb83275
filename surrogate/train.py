"""Training (article 5.4.3): Adam (optionally with decoupled weight decay), L2 loss on the normalised
acceleration of moving particles, random-walk input noise, validation by rollout error, early stopping,
resumable checkpoints.

Files in the output folder:

* ``best.pt``: weights with the lowest validation rollout MSE, with config and dataset stats
  (with ``ema_decay`` set, the exponential moving average of the weights is what is validated and kept);
* ``history.csv``: per epoch the mean training loss and the validation rollout MSE (empty for an epoch that
  ``validate_last`` leaves out: :func:`validated_epochs`), the training wall time
  so far (``seconds``: training and validation, summed over the runs of a resumed job) and where the epoch
  ran: ``threads`` (torch CPU threads per process), ``processes`` (1, or torchrun's), ``device`` (cpu or
  cuda:N) and ``device_name`` (the GPU's or the CPU's model; :func:`surrogate.devices.name`); with the
  model's neighbour cap ``max_neighbours``, also the receivers it capped and the edges it dropped in the
  epoch's training graphs, and their edges before the cap;
* ``snapshot_<c>.pt`` (with ``lr_cycles`` > 1): the validated weights at the end of learning-rate cycle c, in
  best.pt's format, for a snapshot ensemble (``graphdem evaluate --checkpoint snapshot_*.pt``);
* ``last.pt``: the full training state (weights, optimiser, position in the epoch, history,
  best weights; in a fine-tuning phase also the fine-tuning optimiser and the one-step phase's end state).
  It is written every ``checkpoint_every`` steps and at the end of every epoch.
  A run that finds an unfinished ``last.pt`` with the same model, data and training settings
  continues from it, with the same sample order and noise as an uninterrupted run; a finished or
  incompatible one is replaced by a fresh run.

With ``train.finetune`` set (optional; absent: none), the ``epochs`` of one-step training are followed by
``finetune.epochs`` epochs of rollout fine-tuning (:mod:`surrogate.rollout_loss`): from the best validated
weights of the one-step epochs, a fresh optimiser (Adam, or AdamW with the same ``weight_decay``) at the rate
``finetune.lr`` (constant; or, with the optional ``warmup`` and ``lr_final``, ramped up linearly over the phase's
first ``warmup`` steps and then decayed exponentially to ``lr_final`` at its last: :func:`finetune_rate`)
minimises the rollout MSE of ``finetune.batch_size`` train sims per step, the gradient clipped to the norm
``finetune.max_grad_norm`` and backpropagated through the rollout; with ``finetune.ema_decay`` its weights' moving
average is what is validated. Validation and the best checkpoint run on across both phases (if
no fine-tuning epoch beats the one-step best, best.pt stays the one-step model); history.csv gets a ``phase``
column (``onestep``, ``finetune``) and a fine-tuning epoch's ``train_loss`` is its mean rollout loss. A finished
(or interrupted) run whose settings differ only in ``finetune`` is continued, not retrained: its fine-tuning
phase starts again from the end of its one-step epochs, as a run trained in one go would.
"""

from __future__ import annotations

import json
import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import torch
from tqdm import tqdm

from generators import config
from generators.atomic import atomic_path
from surrogate import checkpoint, derived, devices, distributed, runtime
from surrogate.errors import TrainingDiverged
from surrogate.neighbours import PERCENTILE, Histogram
from surrogate.noise import random_walk_position_noise
from surrogate.rollout import rollout, rollout_mse
from surrogate.rollout_loss import rollout_loss
from surrogate.samples import (
    Sim,
    activity_weights,
    epoch_activity_weight,
    epoch_order,
    load_sim,
    sample_activity,
    sample_index,
)
from surrogate.simulator import Graph, LearnedSimulator, build_graph, moving_acceleration, prune_isolated, stack_graphs

log = logging.getLogger("graphdem.train")

# history.csv: per epoch its record, then where it ran (a benchmark card's training cost needs both)
HISTORY_COLUMNS = ("epoch", "step", "train_loss", "valid_rollout_mse", "best", "seconds", "lr",
                   "threads", "processes", "device", "device_name")
# Settings that may change between an interrupted run and its continuation.
_RESUMABLE_CHANGES = ("epochs", "patience", "checkpoint_every", "validate_last")
# the columns a neighbour cap adds to history.csv (sums over the epoch's training graphs)
CAP_HISTORY = ["capped_receivers", "dropped_edges", "edges_before_cap"]


def log_cap(cap: int, stats: dict) -> None:
    """Log the neighbour cap and the share of the train split's receivers and edges it cuts, from the neighbour
    histogram of ``stats.json`` (:mod:`surrogate.neighbours`), or that the stats predate it."""
    counted = stats.get("neighbour_counts")
    if not counted:
        log.info("model.max_neighbours = %d; this stats.json has no neighbour counts (written before they were "
                 "recorded): rerun `graphdem dataset` to see what the cap cuts", cap)
        return
    histogram = Histogram.from_list(counted["histogram"])
    log.info("model.max_neighbours = %d: on the train split at R = %g, %.3g %% of the receivers have more senders "
             "(at most %d, 99th percentile %d) and %.3g %% of the edges are dropped", cap,
             stats["connectivity_radius"], 100 * histogram.capped_fraction(cap), histogram.largest,
             histogram.percentile(PERCENTILE), 100 * histogram.dropped_fraction(cap))


def _generator(*seeds: int) -> torch.Generator:
    return torch.Generator().manual_seed(int(np.random.SeedSequence(list(seeds)).generate_state(1)[0]))


def learning_rate(train_cfg: dict, step: int, total_steps: int) -> float:
    """Adam's learning rate at ``step``: constant ``lr`` (the article), or an exponential decay from
    ``lr`` to ``lr_final`` over the planned steps when ``lr_final`` is set. With ``lr_cycles`` = C (optional,
    absent: 1) the decay restarts: C equal cycles, each decaying from ``lr`` to ``lr_final`` over its
    ``total_steps / C`` steps (a warm restart, Loshchilov & Hutter 2017, with this schedule's exponential shape)."""
    lr, final = float(train_cfg["lr"]), train_cfg.get("lr_final")
    if final is None:
        return lr
    cycle = total_steps / int(train_cfg.get("lr_cycles", 1))        # steps per cycle
    position = step % cycle if step < total_steps else cycle        # past the planned steps: the final rate
    return lr * (float(final) / lr) ** min(position / max(cycle, 1), 1.0)


def finetune_rate(cfg: dict, step: int, total_steps: int) -> float:
    """The fine-tuning phase's learning rate at its ``step`` (0-based) of ``total_steps``: ``lr`` (constant), or
    with ``warmup`` = W (optional, absent: 0) ``lr (step + 1) / W`` over the first W steps, and with ``lr_final``
    (optional, absent or null: none) an exponential decay from ``lr`` after the warm-up to ``lr_final`` at the last
    step, ``lr (lr_final / lr)^((step - W) / (total_steps - W - 1))``."""
    lr, warmup, final = float(cfg["lr"]), int(cfg.get("warmup") or 0), cfg.get("lr_final")
    if step < warmup:
        return lr * (step + 1) / warmup
    if final is None:
        return lr
    span = max(total_steps - warmup - 1, 1)
    return lr * (float(final) / lr) ** min((step - warmup) / span, 1.0)


def snapshot_epochs(train_cfg: dict) -> list[int]:
    """The epochs (1-based) that end a learning-rate cycle, where a run with ``lr_cycles`` > 1 keeps a snapshot of
    its validated weights (``snapshot_<c>.pt``, for a snapshot ensemble); none with one cycle. The cycles must end
    at epoch boundaries and need a decay to restart: a ValueError names the keys otherwise."""
    cycles, epochs = int(train_cfg.get("lr_cycles", 1)), int(train_cfg["epochs"])
    if cycles == 1:
        return []
    if train_cfg.get("lr_final") is None:
        raise ValueError(f"train.lr_cycles = {cycles} restarts the learning-rate decay, but train.lr_final is null "
                         f"(a constant rate): set lr_final, or lr_cycles: 1")
    if epochs % cycles:
        raise ValueError(f"train.lr_cycles = {cycles} must divide train.epochs = {epochs}, so that every cycle "
                         f"ends with an epoch and its validated weights")
    return [epochs // cycles * (c + 1) for c in range(cycles)]


def ema_update(average: dict[str, torch.Tensor], model: torch.nn.Module, decay: float, step: int) -> None:
    """Exponential moving average of the weights, ``a <- d a + (1 - d) w``, with the usual warm-up
    ``d = min(decay, (1 + step) / (10 + step))`` so that the initial weights fade out quickly."""
    d = min(decay, (1 + step) / (10 + step))
    with torch.no_grad():
        for name, value in model.state_dict().items():
            if value.is_floating_point():
                average[name].lerp_(value, 1.0 - d)


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


def make_optimiser(parameters, train_cfg: dict) -> torch.optim.Optimizer:
    """The article's Adam, or with ``weight_decay`` = lambda > 0 (optional; absent: 0) Adam with decoupled weight
    decay (AdamW; Loshchilov and Hutter, ICLR 2019): each step also shrinks every weight by lr x lambda, apart from
    the gradient's moments,

        theta <- theta - lr (m_hat / (sqrt(v_hat) + eps) + lambda theta),

    so a weight the loss does not use decays as (1 - lr lambda) per step. lambda = 0 is exactly Adam."""
    lr = float(train_cfg["lr"])
    decay = train_cfg.get("weight_decay", 0.0)
    if isinstance(decay, bool) or not isinstance(decay, int | float) or not 0 <= decay <= 1:
        raise ValueError(f"train.weight_decay = {decay!r}: allowed a number in [0, 1] (0: Adam without decay)")
    if decay == 0:
        return torch.optim.Adam(parameters, lr=lr)
    return torch.optim.AdamW(parameters, lr=lr, weight_decay=float(decay))


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
    keep = distributed.share(len(batch), world)
    weight = 1.0
    if not keep:
        keep, weight = range(1), 0.0
    drawn = _draws(simulator, sims, batch, noise_std, generator, mirror, pushforward, pushforward_steps, keep)
    windows = [sample.window for sample in drawn]
    radius, cap = simulator.radius, simulator.max_neighbours
    if pushforward_gradient and world.distributed:
        raise ValueError("train.pushforward_gradient: the multi-step loss runs in one training process, "
                         f"got {world.size} (set launch.processes: 1 or pushforward_gradient: false)")
    if pushforward_gradient and type_balance:
        raise ValueError(f"train.type_balance = {type_balance!r} with train.pushforward_gradient: the multi-step loss "
                         f"takes no type weights (set type_balance: 0 or pushforward_gradient: false)")
    step_errors = []                                   # the pushed steps' squared errors (with the gradient)
    with devices.autocast(simulator.lower.device, precision):
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
        graphs = [sample.graph(window, radius, cap) for window, sample in zip(windows, drawn, strict=True)]
        targets = [simulator.target(window, sample.following) for window, sample in zip(windows, drawn, strict=True)]
        stacked = stack_graphs(graphs)
        if counts is not None and weight > 0:          # a weight-0 stand-in sample is not training data
            counts["capped"] += stacked.capped_receivers
            counts["dropped"] += stacked.dropped_edges
            counts["edges"] += stacked.edge_index.shape[1] + stacked.dropped_edges
        # isolated wall particles cannot change a prediction: left out (exact), and only moving particles decoded
        graph, index = prune_isolated(stacked)
        moving = (~graph.kinematic).nonzero().squeeze(1)
        prediction = model(graph, decode=moving)
    squared = (prediction.float() - torch.cat(targets)[index[moving]]) ** 2
    if type_balance:                                   # the stacked graph's moving particles, sample by sample
        squared = squared * torch.cat([type_weights(sample.types[~sample.kinematic], type_balance)
                                       for sample in drawn]).unsqueeze(1)
    if step_errors:
        return torch.cat([*step_errors, squared]).mean()
    if not world.distributed:
        return squared.mean()
    components = sum(int((~sims[s].kinematic).sum()) for s, _ in batch) * squared.shape[-1]
    return squared.sum() * (weight * world.size / components)


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


def validation_mse(simulator: LearnedSimulator, sims: list[Sim]) -> float:
    """Mean over sims of the rollout MSE (docs/surrogate.md); a rollout that blows up scores +inf."""
    simulator.eval()
    values = []
    for sim in sims:
        result = rollout(simulator, sim)
        if result.first_nonfinite is not None:
            log.warning("validation rollout of %s is non-finite from frame %d", sim.id, result.first_nonfinite)
            values.append(math.inf)
            continue
        values.append(float(rollout_mse(result.position, sim.position.numpy(), ~sim.kinematic.numpy(),
                                        simulator.history).mean()))
    simulator.train()
    return float(np.mean(values)) if values else math.nan


def check_finetune(cfg) -> dict | None:
    """``train.finetune`` as given (None: no fine-tuning), checked against the config schema's rule for it (the
    workflow's config is validated whole; this covers callers that pass a train section directly), or a
    ConfigError (a ValueError) naming the key and what is allowed."""
    return config.validate_part(cfg, "#/$defs/train/properties/finetune", "train.finetune")


def _settings(model_cfg: dict, train_cfg: dict, stats: dict, train_ids: list[str]) -> dict:
    """What a run's last.pt must share with the run that continues it: everything but the keys that may change
    (``epochs``, ``patience``, ``checkpoint_every``) and the fine-tuning phase, which a continued run redoes when
    it changed."""
    fixed = {k: v for k, v in train_cfg.items() if k not in _RESUMABLE_CHANGES and k != "finetune"}
    return {"model": model_cfg, "train": fixed, "stats": stats, "train_sims": train_ids}


def _tuning(finetune: dict | None) -> dict | None:
    """The fine-tuning settings that shape its weights: all but ``validate_last``, which only skips validations."""
    return None if finetune is None else {k: v for k, v in finetune.items() if k != "validate_last"}


def validated_epochs(train_cfg: dict) -> tuple[int, int | None]:
    """The first one-step epoch and the first fine-tuning epoch (both 1-based, each counted within its phase; None
    without ``train.finetune``) whose weights are validated: the last ``train.validate_last`` and the last
    ``finetune.validate_last`` epochs of each phase (optional; absent: every epoch; more than the phase has: every
    epoch). An epoch before them is trained but not rolled out on the valid sims, so it never becomes the best and
    never counts towards early stopping; the phase's last epoch is always validated."""
    def first(phase: dict) -> int:
        epochs = int(phase["epochs"])
        return max(1, epochs - int(phase.get("validate_last") or epochs) + 1)

    finetune = train_cfg.get("finetune")
    return first(train_cfg), None if finetune is None else first(finetune)


def train(stats_path: Path, splits_csv: Path, model_cfg: dict, train_cfg: dict, out_dir: Path,
          threads: int = 1, fresh: bool = False, max_steps: int | None = None, progress: bool = True,
          device: str | torch.device = "auto") -> dict:
    """Train (or continue training) and write best.pt, last.pt and history.csv into ``out_dir``.

    ``max_steps`` stops after that many optimiser steps in this call, leaving an unfinished
    ``last.pt`` (used to test resuming; a real interruption behaves the same). ``device`` is where the
    model and the batches live (:mod:`surrogate.devices`); a run may continue on another device than
    the one it started on. Under ``torchrun`` each process trains its share of every batch
    (:mod:`surrogate.distributed`) and the ``threads`` of a node are shared among its processes.
    """
    world = distributed.World.from_env()
    where = devices.resolve(device, world.local_rank if world.distributed else None)
    with distributed.session(world, where):
        return _train(Path(stats_path), Path(splits_csv), model_cfg, train_cfg, Path(out_dir), threads, fresh,
                      max_steps, progress, world, where)


def _train(stats_path: Path, splits_csv: Path, model_cfg: dict, train_cfg: dict, out_dir: Path, threads: int,
           fresh: bool, max_steps: int | None, progress: bool, world: distributed.World,
           device: torch.device) -> dict:
    torch.set_num_threads(max(1, int(threads) // world.local_size))
    snapshots = snapshot_epochs(train_cfg)             # a bad cycle count fails before any data is read
    first_validated, first_tuned = validated_epochs(train_cfg)    # validate_last: the epochs to validate
    progress = progress and world.main
    out_dir.mkdir(parents=True, exist_ok=True)
    stats = json.loads(stats_path.read_text())
    splits = pd.read_csv(splits_csv)
    props = list(model_cfg.get("properties") or [])
    train_paths = list(splits.loc[splits["split"] == "train", "path"])
    valid_paths = list(splits.loc[splits["split"] == "valid", "path"])
    if not train_paths:
        raise ValueError(f"{splits_csv}: the train split is empty")
    if train_cfg.get("valid_sims"):
        valid_paths = valid_paths[: int(train_cfg["valid_sims"])]
    if not valid_paths:
        raise ValueError(f"{splits_csv}: the valid split is empty: the best checkpoint is chosen by validation "
                         f"rollout error, so at least one valid sim is needed")
    train_sims = [load_sim(p, stats, props) for p in tqdm(train_paths, desc="load train", disable=not progress)]
    valid_sims = [load_sim(p, stats, props) for p in valid_paths] if world.main else []   # rank 0 validates
    k = int(model_cfg["history"])
    index = sample_index(train_sims, k, int(model_cfg.get("bundle", 1)))
    activity_weight = float(train_cfg.get("activity_weight", 0))        # optional; absent: uniform epochs
    activity_final = train_cfg.get("activity_weight_final")             # optional; absent: the same every epoch
    activity_final = None if activity_final is None else float(activity_final)
    activity = sample_activity(train_sims, index) if activity_weight or activity_final else None

    planned = int(train_cfg["epochs"])

    def weight_of(epoch: int) -> float:
        return epoch_activity_weight(activity_weight, activity_final, epoch, planned)

    def draw_weights(epoch: int) -> torch.Tensor | None:
        return None if activity is None else activity_weights(activity, weight_of(epoch))

    if activity is not None:
        ends = [(0, "train.activity_weight")]
        ends += [(planned - 1, "train.activity_weight_final")] if activity_final is not None else []
        for epoch, name in ends:
            weights = draw_weights(epoch)
            share = 10.0 if weights is None else 100 * float(
                torch.topk(weights, max(1, len(index) // 10)).values.sum() / weights.sum())
            log.info("%s = %g (epoch %d): samples drawn in proportion to 1 + w x activity / mean activity; the "
                     "busiest 10 %% of the samples get %.0f %% of the draws", name, weight_of(epoch), epoch + 1, share)
    batch_size = int(train_cfg["batch_size"])
    n_batches = math.ceil(len(index) / batch_size)
    train_cfg = derived.resolve(train_cfg, stats, n_batches)
    for name, rule in train_cfg.get("derived", {}).items():
        log.info("train.%s = %.6g, derived (%s)", name, train_cfg[name], rule["rule"])
    seed = int(train_cfg["seed"])
    precision = str(train_cfg["precision"])
    finetune = check_finetune(train_cfg.get("finetune"))
    if finetune is not None and world.distributed:
        raise ValueError(f"train.finetune: rollout fine-tuning runs in one training process, got {world.size} "
                         f"(set launch.processes: 1, or finetune: null)")
    settings = _settings(model_cfg, train_cfg, stats, [s.id for s in train_sims])
    if world.distributed and batch_size < world.size:
        log.warning("batch_size %d < %d processes: %d of them compute a sample with weight 0 at every step",
                    batch_size, world.size, world.size - batch_size)

    torch.manual_seed(seed)
    simulator = LearnedSimulator(stats, model_cfg).to(device)
    optimiser = make_optimiser(simulator.parameters(), train_cfg)
    state = {"epoch": 0, "batch": 0, "step": 0, "history": [], "best_mse": math.inf, "best_epoch": -1,
             "best_step": 0, "bad_epochs": 0, "finished": False, "loss_sum": 0.0, "loss_count": 0, "seconds": 0.0,
             # the learning-rate schedule is fixed when a run starts, so a resumed run follows it exactly
             "total_steps": int(train_cfg["epochs"]) * n_batches}
    cap = simulator.max_neighbours
    if cap is not None:
        log_cap(cap, stats)
        state.update(capped_sum=0, dropped_sum=0, edges_sum=0)       # the epoch's training graphs so far
    best_weights = None
    decay = train_cfg.get("ema_decay")
    average = {k: v.detach().clone() for k, v in simulator.state_dict().items()} if decay is not None else None
    validator = LearnedSimulator(stats, model_cfg).to(device) if decay is not None else simulator
    if train_cfg.get("compile"):
        runtime.compile_forward(simulator)
        if validator is not simulator:
            runtime.compile_forward(validator)
        log.info("train.compile: the forward passes of training and validation run through torch.compile")
    last = out_dir / "last.pt"
    tuner = None                                   # the fine-tuning phase's optimiser, moving average and start
    rolled_back = False                            # a run whose fine-tuning was removed ends at its one-step end
    if last.exists() and not fresh:
        try:
            saved = checkpoint.load(last)
        except checkpoint.CheckpointError as exc:
            log.warning("ignoring %s: %s", last, exc)
            saved = None
        saved_state = {} if saved is None else saved["json"].get("state", {})
        same_finetune = saved is not None and _tuning(saved["json"].get("train", {}).get("finetune")) == _tuning(
            json.loads(json.dumps(finetune)))
        if saved is None:
            pass
        elif saved["json"].get("settings") != json.loads(json.dumps(settings)):
            log.info("%s was trained with other settings or data: starting a fresh run", last)
        elif "finetune" in saved_state and finetune is None:
            state, best_weights = _one_step_end(saved, finished=True)
            rolled_back = True
            simulator.load_state_dict(saved["model"])
            log.info("%s: train.finetune was removed; the run ends where its one-step epochs ended (epoch %d)",
                     last, state["epoch"])
        elif (finetune is not None and (not same_finetune or "finetune" not in saved_state)
              and (saved_state.get("finished") or "finetune" in saved_state)
              and saved_state.get("total_steps") == int(train_cfg["epochs"]) * n_batches):
            # its one-step epochs are done and its fine-tuning (none, or another) is not this one: redo that phase
            state, best_weights = _one_step_end(saved, finished=False)
            state["epoch"] = int(train_cfg["epochs"])          # also after an early stop: fine-tuning is next
            simulator.load_state_dict(saved["model"])
            optimiser.load_state_dict(saved["optimiser"])
            if average is not None:
                average = {k: v.to(device) for k, v in saved["average_model"].items()}
            log.info("%s: its %d one-step epochs are done; fine-tuning (train.finetune) starts from their end",
                     last, len(state["history"]))
        elif saved_state.get("finished"):
            log.info("%s is a finished run: starting a fresh one", last)
        else:
            simulator.load_state_dict(saved["model"])
            optimiser.load_state_dict(saved["optimiser"])
            best_weights = saved.get("best_model")
            if average is not None:
                average = {k: v.to(device) for k, v in saved["average_model"].items()}
            state = saved["json"]["state"]
            if "finetune" in state:
                tuner = _Tuner.resumed(saved, simulator, train_cfg, finetune, device, len(train_sims))
            log.info("resuming from %s at epoch %d, batch %d, step %d", last, state["epoch"], state["batch"],
                     state["step"])
            planned = state["total_steps"] // n_batches          # the schedule fixed when the run started
            if snapshots and planned != int(train_cfg["epochs"]):
                snapshots = snapshot_epochs({**train_cfg, "epochs": planned})
                log.info("train.epochs changed from %d to %s: the learning-rate cycles and their snapshots stay "
                         "those of the %d epochs the run started with (epochs %s)", planned, train_cfg["epochs"],
                         planned, snapshots)
    model = distributed.wrap(simulator, world, device)     # after resuming: DDP starts from rank 0's weights
    # where each epoch ran (history.csv): a resumed run may continue on other hardware
    hardware = [torch.get_num_threads(), world.size, str(device), devices.name(device)]

    def meta() -> dict:
        return {"model": model_cfg, "train": train_cfg, "stats": stats, "settings": settings, "state": state}

    def save_last() -> None:
        payload = {"model": simulator.state_dict(), "optimiser": optimiser.state_dict(), "json": meta()}
        if best_weights is not None:
            payload["best_model"] = best_weights
        if average is not None:
            payload["average_model"] = average
        if tuner is not None:
            payload.update(tuner.payload())
        checkpoint.save(last, payload)

    def save_outputs() -> None:
        # a run resumed from a last.pt written before the hardware columns has shorter rows: blank there (such a
        # run has no neighbour cap: the cap is newer than the hardware columns)
        columns = list(HISTORY_COLUMNS) + (CAP_HISTORY if cap is not None else [])
        history = pd.DataFrame([row[:len(columns)] + [None] * (len(columns) - len(row)) for row in state["history"]],
                               columns=columns)
        if finetune is not None:                   # an epoch past the one-step ones is a fine-tuning epoch
            start = state.get("finetune", {}).get("start_epoch", int(train_cfg["epochs"]))
            history["phase"] = np.where(history["epoch"] > start, "finetune", "onestep")
        with atomic_path(out_dir / "history.csv") as tmp:
            history.to_csv(tmp, index=False)
        if best_weights is not None:
            checkpoint.save(out_dir / "best.pt", {"model": best_weights, "json": {
                "model": model_cfg, "train": train_cfg, "stats": stats, "epoch": state["best_epoch"],
                "valid_rollout_mse": state["best_mse"], "step": state["best_step"]}})

    epochs, patience = int(train_cfg["epochs"]), int(train_cfg["patience"])
    total_epochs = epochs + (finetune["epochs"] if finetune is not None else 0)
    every = int(train_cfg["checkpoint_every"])
    steps_this_call = 0
    simulator.train()
    clock = time.perf_counter()
    while state["epoch"] < total_epochs and not state["finished"]:
        epoch = state["epoch"]
        if epoch >= epochs:                            # the fine-tuning phase (train.finetune)
            if tuner is None:
                tuner = _Tuner.start(state, simulator, optimiser, best_weights, train_cfg, finetune, device,
                                     len(train_sims))
            order = torch.randperm(len(train_sims), generator=_generator(seed, epoch)).tolist()
            size = int(finetune["batch_size"])
            batches = [[train_sims[i] for i in order[b:b + size]] for b in range(0, len(order), size)]
        else:
            order = epoch_order(len(index), draw_weights(epoch), _generator(seed, epoch))
            batches = None
        count = len(batches) if batches is not None else n_batches
        bar = tqdm(range(state["batch"], count), desc=f"epoch {epoch + 1}/{total_epochs}"
                   + (" (fine-tuning)" if batches is not None else ""), unit="batch", disable=not progress,
                   mininterval=2.0)
        for b in bar:
            if batches is not None:
                loss = tuner.loss(simulator, batches[b], finetune["frames"], _generator(seed, epoch, b, 2),
                                  precision)
                value = float(loss.detach())
            else:
                batch = [index[i] for i in order[b * batch_size:(b + 1) * batch_size]]
                counts = {"capped": 0, "dropped": 0, "edges": 0} if cap is not None else None
                loss = batch_loss(simulator, train_sims, batch, float(train_cfg["noise_std"]),
                                  _generator(seed, epoch, b, 1), mirror=bool(train_cfg["mirror"]),
                                  pushforward=float(train_cfg["pushforward"]),
                                  pushforward_steps=int(train_cfg["pushforward_steps"]), world=world, model=model,
                                  precision=precision, counts=counts,
                                  pushforward_gradient=bool(train_cfg.get("pushforward_gradient", False)),
                                  type_balance=float(train_cfg.get("type_balance", 0.0)))
                value = distributed.mean(loss, world)          # the batch's loss, the same on every process
                if counts is not None:                         # summed over the processes' shares of the batch
                    summed = distributed.total(torch.tensor([counts["capped"], counts["dropped"], counts["edges"]],
                                                            dtype=torch.int64, device=device), world)
                    for key, number in zip(("capped_sum", "dropped_sum", "edges_sum"), summed.tolist(), strict=True):
                        state[key] += int(number)
            if not math.isfinite(value):
                where = (", ".join(sim.id for sim in batches[b]) if batches is not None
                         else ", ".join(f"{train_sims[s].id} frame {t}" for s, t in batch))
                raise TrainingDiverged(
                    f"non-finite training loss ({value}) at step {state['step'] + 1} (epoch {epoch + 1}, "
                    f"batch {b + 1}) on {'the rollouts of ' if batches is not None else 'samples: '}{where}; "
                    f"the last good state is in {last}")
            if batches is not None:
                tuner.step(loss, simulator, state)
            else:
                for group in optimiser.param_groups:
                    group["lr"] = learning_rate(train_cfg, state["step"], state["total_steps"])
                optimiser.zero_grad(set_to_none=True)
                loss.backward()
                optimiser.step()
                if average is not None:
                    ema_update(average, simulator, float(decay), state["step"])
            state["step"] += 1
            state["batch"] = b + 1
            state["loss_sum"] += value
            state["loss_count"] += 1
            steps_this_call += 1
            bar.set_postfix(loss=f"{state['loss_sum'] / state['loss_count']:.4g}", refresh=False)
            if max_steps is not None and steps_this_call >= max_steps:
                state["seconds"] += time.perf_counter() - clock
                if world.main:
                    save_last()
                    save_outputs()
                distributed.barrier(world)
                log.info("stopped after %d steps as asked (step %d); rerun to continue", max_steps, state["step"])
                return state
            if every and state["step"] % every == 0:
                state["seconds"] += time.perf_counter() - clock
                clock = time.perf_counter()
                if world.main:
                    save_last()
        bar.close()
        if world.main:
            if batches is not None:                    # fine-tuning: its own average, to the end (validate_last)
                best_weights = _end_epoch(state, tuner.validator(validator, simulator), tuner.average, valid_sims,
                                          total_epochs, total_epochs, tuner.lr, clock, hardware,
                                          validate=epoch + 1 - epochs >= first_tuned) or best_weights
            else:
                best_weights = _end_epoch(state, validator, average, valid_sims, patience, epochs,
                                          optimiser.param_groups[0]["lr"], clock, hardware,
                                          validate=epoch + 1 >= first_validated or epoch + 1 in snapshots
                                          ) or best_weights
                if state["finished"] and finetune is not None:     # the one-step phase ended: fine-tuning next
                    state.update(finished=False, epoch=epochs)
            if epoch + 1 in snapshots and batches is None:         # a cycle ended: keep its validated weights
                checkpoint.save(out_dir / f"snapshot_{snapshots.index(state['epoch']) + 1}.pt", {
                    "model": {k: v.detach().to("cpu", copy=True) for k, v in validator.state_dict().items()},
                    "json": {"model": model_cfg, "train": train_cfg, "stats": stats, "epoch": state["epoch"],
                             "valid_rollout_mse": state["history"][-1][3], "step": state["step"]}})
            save_outputs()      # outputs first: a kill in between never leaves a finished state without them
            save_last()
        state = distributed.from_main(state, world)    # the others wait here for rank 0's validation
        clock = time.perf_counter()
    if rolled_back and world.main:                 # its outputs are rewritten as they stood after the one-step epochs
        save_outputs()
        save_last()
    if state["best_epoch"] == -1:
        raise ValueError(f"no epoch was completed (epochs = {epochs}): no best checkpoint")
    if not math.isfinite(state["best_mse"]):
        log.warning("every validation rollout blew up: best.pt holds epoch %d only because it came first",
                    state["best_epoch"])
    return state


class _Tuner:
    """The rollout fine-tuning phase (``train.finetune``): its optimiser at the rate of :func:`finetune_rate`, the
    gradient clip, the moving average of its weights (None without ``ema_decay``) and where the phase started."""

    def __init__(self, optimiser: torch.optim.Optimizer, cfg: dict, average: dict | None, start_step: int,
                 onestep_best: dict, n_train: int):
        self.optimiser, self.cfg, self.average, self.start_step = optimiser, cfg, average, start_step
        self.onestep_best = onestep_best           # the one-step phase's best weights, to redo the phase from
        self.total_steps = int(cfg["epochs"]) * math.ceil(n_train / int(cfg["batch_size"]))
        self.lr = finetune_rate(cfg, 0, self.total_steps)     # the rate of the latest step (history's lr column)

    @classmethod
    def start(cls, state: dict, simulator: LearnedSimulator, optimiser: torch.optim.Optimizer, best: dict | None,
              train_cfg: dict, cfg: dict, device: torch.device, n_train: int) -> _Tuner:
        """Begin the phase (``n_train`` train sims): remember the one-step end (in ``state``), load the one-step
        best weights, and start a fresh optimiser (the one-step phase's kind, at ``cfg['lr']``) and moving average."""
        if best is None:
            raise ValueError("train.finetune: the one-step epochs left no validated weights to fine-tune")
        onestep = json.loads(json.dumps({k: v for k, v in state.items() if k != "finetune"}))
        state["finetune"] = {"start_epoch": state["epoch"], "start_step": state["step"], "onestep": onestep}
        state["bad_epochs"] = 0
        simulator.load_state_dict({k: v.to(device) for k, v in best.items()})
        schedule = (f", warm-up over {cfg['warmup']} steps" if cfg.get("warmup") else "") + (
            f", decaying to {cfg['lr_final']:g}" if cfg.get("lr_final") is not None else "")
        log.info("fine-tuning (train.finetune): %d epochs of rollouts of %s frames, %d sims per step, lr %g%s, from "
                 "the one-step best (epoch %d, valid %.5g)", cfg["epochs"], cfg["frames"] or "all",
                 cfg["batch_size"], cfg["lr"], schedule, state["best_epoch"], state["best_mse"])
        average = ({k: v.detach().clone() for k, v in simulator.state_dict().items()}
                   if cfg["ema_decay"] is not None else None)
        tuned = make_optimiser(simulator.parameters(), {**train_cfg, "lr": cfg["lr"]})
        return cls(tuned, cfg, average, state["step"], best, n_train)

    @classmethod
    def resumed(cls, saved: dict, simulator: LearnedSimulator, train_cfg: dict, cfg: dict,
                device: torch.device, n_train: int) -> _Tuner:
        """The phase of an interrupted run, from its last.pt ``saved`` (``n_train`` train sims)."""
        tuned = make_optimiser(simulator.parameters(), {**train_cfg, "lr": cfg["lr"]})
        tuned.load_state_dict(saved["finetune_optimiser"])
        average = saved.get("finetune_average")
        average = None if average is None else {k: v.to(device) for k, v in average.items()}
        tuner = cls(tuned, cfg, average, int(saved["json"]["state"]["finetune"]["start_step"]),
                    saved["onestep_best"], n_train)
        tuner.lr = finetune_rate(cfg, max(int(saved["json"]["state"]["step"]) - tuner.start_step - 1, 0),
                                 tuner.total_steps)
        return tuner

    def payload(self) -> dict:
        """What last.pt keeps of the phase."""
        return {"finetune_optimiser": self.optimiser.state_dict(), "finetune_average": self.average,
                "onestep_best": self.onestep_best}

    def loss(self, simulator: LearnedSimulator, sims: list[Sim], frames: int | None, generator: torch.Generator,
             precision: str) -> torch.Tensor:
        with devices.autocast(simulator.lower.device, precision):
            return rollout_loss(simulator, sims, frames, generator)

    def step(self, loss: torch.Tensor, simulator: LearnedSimulator, state: dict) -> None:
        """One optimiser step on ``loss`` at the phase's rate for the step: the gradient clipped to ``max_grad_norm``,
        then the moving average."""
        self.lr = finetune_rate(self.cfg, state["step"] - self.start_step, self.total_steps)
        for group in self.optimiser.param_groups:
            group["lr"] = self.lr
        self.optimiser.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(simulator.parameters(), float(self.cfg["max_grad_norm"]))
        self.optimiser.step()
        if self.average is not None:
            ema_update(self.average, simulator, float(self.cfg["ema_decay"]), state["step"] - self.start_step)

    def validator(self, validator: LearnedSimulator, simulator: LearnedSimulator) -> LearnedSimulator:
        """What a fine-tuning epoch validates: the moving average (loaded into ``validator``), or the weights."""
        return simulator if self.average is None else validator


def _one_step_end(saved: dict, finished: bool) -> tuple[dict, dict | None]:
    """A saved run's state and best weights at the end of its one-step epochs (its fine-tuning phase undone)."""
    state = saved["json"]["state"]
    if "finetune" in state:
        return {**state["finetune"]["onestep"], "finished": finished}, saved["onestep_best"]
    return {**state, "finished": finished}, saved.get("best_model")


def _end_epoch(state: dict, validator: LearnedSimulator, average: dict | None, valid_sims: list[Sim], patience: int,
               epochs: int, lr: float, clock: float, hardware: list, validate: bool = True
               ) -> dict[str, torch.Tensor] | None:
    """Validate the epoch's weights (their average, with ``ema_decay``), record the epoch in ``state`` (with the
    ``hardware`` it ran on: threads, processes, device, device name) and close it; the weights to keep as the best,
    on the CPU, where they improved, else None. With ``validate`` False (an epoch before its phase's last
    ``validate_last``) the epoch is recorded without a validation error (NaN), is not the best and does not count
    towards ``patience``."""
    epoch = state["epoch"]
    train_loss = state["loss_sum"] / max(state["loss_count"], 1)
    best, improved, valid = None, False, math.nan
    if validate:
        if average is not None:
            validator.load_state_dict(average)
        valid = validation_mse(validator, valid_sims)
        # the first epoch is the best so far even when its validation rollouts all blew up (+inf)
        improved = valid < state["best_mse"] or state["best_epoch"] == -1
        if improved:
            state["best_mse"], state["best_epoch"], state["bad_epochs"] = valid, epoch + 1, 0
            state["best_step"] = state["step"]
            best = {k: v.detach().to("cpu", copy=True) for k, v in validator.state_dict().items()}
        else:
            state["bad_epochs"] += 1
    state["seconds"] += time.perf_counter() - clock
    row = [epoch + 1, state["step"], train_loss, valid, improved, round(state["seconds"], 2), lr, *hardware]
    if validate:
        log.info("epoch %d: train loss %.5g, valid rollout MSE %.5g m^2%s", epoch + 1, train_loss, valid,
                 " (best)" if improved else "")
    else:
        log.info("epoch %d: train loss %.5g, not validated (validate_last: only the phase's last "
                 "epochs are)", epoch + 1, train_loss)
    if "capped_sum" in state:                      # a neighbour cap: what it cut from the epoch's training graphs
        capped, dropped, edges = state["capped_sum"], state["dropped_sum"], state["edges_sum"]
        row += [capped, dropped, edges]
        log.info("epoch %d: the neighbour cap capped %d receivers and dropped %d of %d edges (%.3g %%) of the "
                 "training graphs", epoch + 1, capped, dropped, edges, 100 * dropped / max(edges, 1))
        state.update(capped_sum=0, dropped_sum=0, edges_sum=0)
    state["history"].append(row)
    state.update(epoch=epoch + 1, batch=0, loss_sum=0.0, loss_count=0)
    if state["bad_epochs"] >= patience:
        log.info("early stopping: no improvement for %d epochs", patience)
        state["finished"] = True
    if state["epoch"] >= epochs:
        state["finished"] = True
    return best
