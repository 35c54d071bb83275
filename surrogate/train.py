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

The parts are in :mod:`surrogate.training` (the loss, the schedules, the two phases, the state and the epoch loop);
this module is the entry and names them.
"""


from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import pandas as pd
import torch
from tqdm import tqdm

from generators import config
from surrogate import derived, devices, distributed, runtime
from surrogate.errors import TrainingDiverged
from surrogate.neighbours import PERCENTILE, Histogram
from surrogate.samples import Sim, load_sim, sample_activity, sample_index
from surrogate.simulator import LearnedSimulator
from surrogate.training.loop import run_epochs, validation_mse
from surrogate.training.losses import batch_loss, mirror_x, type_weights
from surrogate.training.phases import Activity, FinetunePhase, OneStepPhase, Run
from surrogate.training.schedules import (
    ema_update,
    finetune_rate,
    learning_rate,
    make_optimiser,
    snapshot_epochs,
    validated_epochs,
)
from surrogate.training.state import CAP_HISTORY, HISTORY_COLUMNS, RunFiles, RunState, fresh_progress, settings

__all__ = ["CAP_HISTORY", "HISTORY_COLUMNS", "TrainingDiverged", "batch_loss", "check_finetune", "ema_update",
           "finetune_rate", "learning_rate", "log_cap", "make_optimiser", "mirror_x", "snapshot_epochs", "train",
           "type_weights", "validated_epochs", "validation_mse"]

log = logging.getLogger("graphdem.train")


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


def check_finetune(cfg) -> dict | None:
    """``train.finetune`` as given (None: no fine-tuning), checked against the config schema's rule for it (the
    workflow's config is validated whole; this covers callers that pass a train section directly), or a
    ConfigError (a ValueError) naming the key and what is allowed."""
    return config.validate_part(cfg, "#/$defs/train/properties/finetune", "train.finetune")


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
    """A run: its data, its model and state (fresh, or continued from last.pt), then its phases' epochs."""
    torch.set_num_threads(max(1, int(threads) // world.local_size))
    snapshots = snapshot_epochs(train_cfg)             # a bad cycle count fails before any data is read
    first_validated, first_tuned = validated_epochs(train_cfg)    # validate_last: the epochs to validate
    progress = progress and world.main
    out_dir.mkdir(parents=True, exist_ok=True)
    stats = json.loads(stats_path.read_text())
    train_sims, valid_sims = _sims(splits_csv, stats, model_cfg, train_cfg, world, progress)
    index = sample_index(train_sims, int(model_cfg["history"]), int(model_cfg.get("bundle", 1)))
    activity = _activity(train_sims, index, train_cfg)
    batch_size = int(train_cfg["batch_size"])
    n_batches = math.ceil(len(index) / batch_size)
    train_cfg = derived.resolve(train_cfg, stats, n_batches)
    for name, rule in train_cfg.get("derived", {}).items():
        log.info("train.%s = %.6g, derived (%s)", name, train_cfg[name], rule["rule"])
    finetune = check_finetune(train_cfg.get("finetune"))
    if finetune is not None and world.distributed:
        raise ValueError(f"train.finetune: rollout fine-tuning runs in one training process, got {world.size} "
                         f"(set launch.processes: 1, or finetune: null)")
    same = settings(model_cfg, train_cfg, stats, [s.id for s in train_sims])     # what a continuation must share
    if world.distributed and batch_size < world.size:
        log.warning("batch_size %d < %d processes: %d of them compute a sample with weight 0 at every step",
                    batch_size, world.size, world.size - batch_size)
    state, validator = _start(stats, model_cfg, train_cfg, n_batches, device)
    files = RunFiles(out_dir, model_cfg, train_cfg, stats, same, finetune, state.simulator.max_neighbours is not None)
    how = state.restore(files.read_last(fresh), files, device)
    if how == "resumed":
        planned = state.progress["total_steps"] // n_batches          # the schedule fixed when the run started
        if activity is not None:
            activity.planned = planned
        if snapshots and planned != int(train_cfg["epochs"]):
            snapshots = snapshot_epochs({**train_cfg, "epochs": planned})
            log.info("train.epochs changed from %d to %s: the learning-rate cycles and their snapshots stay "
                     "those of the %d epochs the run started with (epochs %s)", planned, train_cfg["epochs"],
                     planned, snapshots)
    simulator = state.simulator
    model = distributed.wrap(simulator, world, device)     # after resuming: DDP starts from rank 0's weights
    # where each epoch ran (history.csv): a resumed run may continue on other hardware
    hardware = [torch.get_num_threads(), world.size, str(device), devices.name(device)]
    run = Run(simulator, model, validator, train_sims, valid_sims, index, train_cfg, finetune, world, device,
              hardware, files, progress)
    # the one-step loss is looked up here, when a run starts, so that a test may replace train.batch_loss
    phases = [OneStepPhase(run, state, batch_loss, activity, snapshots, first_validated)]
    phases += [FinetunePhase(run, state, first_tuned)] if finetune is not None else []
    simulator.train()
    if not run_epochs(run, state, phases, max_steps):
        return state.progress                       # stopped as asked (max_steps)
    if how == "rolled_back" and world.main:        # its outputs are rewritten as they stood after the one-step epochs
        files.write_outputs(state)
        files.write_last(state)
    return _checked_end(state.progress, int(train_cfg["epochs"]))


def _sims(splits_csv: Path, stats: dict, model_cfg: dict, train_cfg: dict, world: distributed.World,
          progress: bool) -> tuple[list[Sim], list[Sim]]:
    """The train sims, and rank 0's valid sims (``train.valid_sims``: the first that many; it validates)."""
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
    return train_sims, valid_sims


def _activity(train_sims: list[Sim], index: list[tuple[int, int]], train_cfg: dict) -> Activity | None:
    """The activity weighting of the one-step draws (None: uniform epochs), with a log line of what it does to the
    first and (with ``activity_weight_final``) the last epoch's draws."""
    weight = float(train_cfg.get("activity_weight", 0))        # optional; absent: uniform epochs
    final = train_cfg.get("activity_weight_final")             # optional; absent: the same every epoch
    final = None if final is None else float(final)
    if not (weight or final):
        return None
    activity = Activity(sample_activity(train_sims, index), weight, final, int(train_cfg["epochs"]))
    ends = [(0, "train.activity_weight")]
    ends += [(activity.planned - 1, "train.activity_weight_final")] if final is not None else []
    for epoch, name in ends:
        weights = activity.draw_weights(epoch)
        share = 10.0 if weights is None else 100 * float(
            torch.topk(weights, max(1, len(index) // 10)).values.sum() / weights.sum())
        log.info("%s = %g (epoch %d): samples drawn in proportion to 1 + w x activity / mean activity; the "
                 "busiest 10 %% of the samples get %.0f %% of the draws", name, activity.weight_of(epoch), epoch + 1,
                 share)
    return activity


def _start(stats: dict, model_cfg: dict, train_cfg: dict, n_batches: int,
           device: torch.device) -> tuple[RunState, LearnedSimulator]:
    """A fresh run's state (the model initialised from ``train.seed``, its optimiser and weight average) and the
    model validation loads the weight average into (the trained model itself without one)."""
    torch.manual_seed(int(train_cfg["seed"]))
    simulator = LearnedSimulator(stats, model_cfg).to(device)
    optimiser = make_optimiser(simulator.parameters(), train_cfg)
    cap = simulator.max_neighbours
    if cap is not None:
        log_cap(cap, stats)
    decay = train_cfg.get("ema_decay")
    average = {k: v.detach().clone() for k, v in simulator.state_dict().items()} if decay is not None else None
    validator = LearnedSimulator(stats, model_cfg).to(device) if decay is not None else simulator
    if train_cfg.get("compile"):
        runtime.compile_forward(simulator)
        if validator is not simulator:
            runtime.compile_forward(validator)
        log.info("train.compile: the forward passes of training and validation run through torch.compile")
    progress = fresh_progress(int(train_cfg["epochs"]) * n_batches, cap is not None)
    return RunState(progress, simulator, optimiser, average), validator


def _checked_end(progress: dict, epochs: int) -> dict:
    """The finished run's ``progress``, once it is sure to have a best checkpoint (a warning where every validation
    rollout blew up)."""
    if progress["best_epoch"] == -1:
        raise ValueError(f"no epoch was completed (epochs = {epochs}): no best checkpoint")
    if not math.isfinite(progress["best_mse"]):
        log.warning("every validation rollout blew up: best.pt holds epoch %d only because it came first",
                    progress["best_epoch"])
    return progress
