"""The two phases of a training run (docs/surrogate.md, Training and Rollout fine-tuning): one-step training, then
(with ``train.finetune``) rollout fine-tuning. Each gives the epoch loop (:mod:`surrogate.training.loop`) the same
few things: its start, an epoch's batches, one optimiser step, what to validate and what follows its epochs."""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np
import torch

from surrogate import devices, distributed
from surrogate.errors import TrainingDiverged
from surrogate.rollout_loss import rollout_loss
from surrogate.samples import Sim, activity_weights, epoch_activity_weight, epoch_order
from surrogate.simulator import LearnedSimulator
from surrogate.training.schedules import ema_update, finetune_rate, generator, learning_rate
from surrogate.training.state import RunFiles, RunState, Tuned

log = logging.getLogger("graphdem.train")


@dataclass
class Run:
    """What a run trains with: the model being trained (``simulator``; ``model``, the module whose forward pass
    carries the gradient: DDP on several processes), the model a weight average is validated in (``validator``:
    ``simulator`` itself without one), the data, the settings, where it runs and its files."""

    simulator: LearnedSimulator
    model: torch.nn.Module
    validator: LearnedSimulator
    train_sims: list[Sim]
    valid_sims: list[Sim]          # rank 0's only: it validates
    index: list[tuple[int, int]]   # the one-step samples: (sim, last frame of the window)
    train_cfg: dict                # with its derived values
    finetune: dict | None
    world: distributed.World
    device: torch.device
    hardware: list                 # history.csv: threads, processes, device, device name
    files: RunFiles
    show_progress: bool            # progress bars (rank 0's)

    @property
    def seed(self) -> int:
        return int(self.train_cfg["seed"])

    @property
    def precision(self) -> str:
        return str(self.train_cfg["precision"])


@dataclass
class Activity:
    """The activity weighting of the one-step epochs' draws (``train.activity_weight``, optional
    ``activity_weight_final``): each sample's activity, and the weight of an epoch of the ``planned`` epochs."""

    activity: np.ndarray
    weight: float
    final: float | None
    planned: int

    def weight_of(self, epoch: int) -> float:
        return epoch_activity_weight(self.weight, self.final, epoch, self.planned)

    def draw_weights(self, epoch: int) -> torch.Tensor | None:
        return activity_weights(self.activity, self.weight_of(epoch))


class Phase(Protocol):
    """What the epoch loop (:func:`surrogate.training.loop.run_epochs`) asks of a phase."""

    label: str          # the progress bar's, after the epoch
    end: int            # the phase's epochs end before this one (0-based, counted over the run)
    patience: int       # validated epochs without a better one after which the run stops
    lr: float           # the rate of the latest step (history.csv)

    def begin(self) -> None:
        """Start the phase, or take up a resumed one (called before each of its epochs; once is what counts)."""

    def batches(self, epoch: int) -> list:
        """The epoch's batches, drawn from the run's seed and the epoch."""

    def step(self, epoch: int, b: int, batch) -> float:
        """One optimiser step on batch ``b``; its loss."""

    def validated(self) -> tuple[LearnedSimulator, dict | None]:
        """The model validation rolls out, and the weights to load into it first (None: its own)."""

    def validates(self, epoch: int) -> bool:
        """Whether ``epoch`` is validated (``validate_last``)."""

    def after_epoch(self, epoch: int) -> None:
        """On rank 0, what follows the epoch's record (before the files are written)."""


def _check_finite(value: float, progress: dict, epoch: int, b: int, where: str, last: Path) -> None:
    if not math.isfinite(value):
        raise TrainingDiverged(
            f"non-finite training loss ({value}) at step {progress['step'] + 1} (epoch {epoch + 1}, "
            f"batch {b + 1}) on {where}; the last good state is in {last}")


class OneStepPhase:
    """One-step training (article 5.4.3), the run's first ``train.epochs`` epochs: per step a mini-batch of samples
    and the L2 loss of the normalised acceleration over their moving particles,
    ``L = mean_i |a_hat_i - a_i|^2`` (``loss``: :func:`surrogate.training.losses.batch_loss`, with random-walk input
    noise, mirror and pushforward draws), Adam (AdamW with ``weight_decay``) at the rate of :func:`learning_rate`,
    and the weights' moving average with ``ema_decay``. Each epoch draws its samples' order (by activity, with
    ``activity``); a learning-rate cycle's last epoch keeps a snapshot of the validated weights."""

    label = ""

    def __init__(self, run: Run, state: RunState, loss: Callable[..., torch.Tensor], activity: Activity | None,
                 snapshots: list[int], first_validated: int):
        self.run, self.state, self.loss, self.activity = run, state, loss, activity
        self.snapshots, self.first_validated = snapshots, first_validated
        cfg = run.train_cfg
        self.end, self.patience = int(cfg["epochs"]), int(cfg["patience"])    # the phase ends before epoch `end`
        self.batch_size = int(cfg["batch_size"])

    @property
    def lr(self) -> float:
        return self.state.optimiser.param_groups[0]["lr"]

    def begin(self) -> None:
        """Nothing to start: its optimiser and weight average are the run's from its first step."""

    def batches(self, epoch: int) -> list[list[tuple[int, int]]]:
        index = self.run.index
        weights = None if self.activity is None else self.activity.draw_weights(epoch)
        order = epoch_order(len(index), weights, generator(self.run.seed, epoch))
        return [[index[i] for i in order[b:b + self.batch_size]] for b in range(0, len(index), self.batch_size)]

    def step(self, epoch: int, b: int, batch: list[tuple[int, int]]) -> float:
        """One optimiser step on the batch's loss (its value, the same on every process), the neighbour cap's cuts
        summed into the state; a non-finite loss stops the run (TrainingDiverged) before the step."""
        run, cfg, progress = self.run, self.run.train_cfg, self.state.progress
        counts = {"capped": 0, "dropped": 0, "edges": 0} if run.simulator.max_neighbours is not None else None
        loss = self.loss(run.simulator, run.train_sims, batch, float(cfg["noise_std"]),
                         generator(run.seed, epoch, b, 1), mirror=bool(cfg["mirror"]),
                         pushforward=float(cfg["pushforward"]), pushforward_steps=int(cfg["pushforward_steps"]),
                         world=run.world, model=run.model, precision=run.precision, counts=counts,
                         pushforward_gradient=bool(cfg.get("pushforward_gradient", False)),
                         type_balance=float(cfg.get("type_balance", 0.0)))
        value = distributed.mean(loss, run.world)          # the batch's loss, the same on every process
        if counts is not None:                             # summed over the processes' shares of the batch
            summed = distributed.total(torch.tensor([counts["capped"], counts["dropped"], counts["edges"]],
                                                    dtype=torch.int64, device=run.device), run.world)
            for key, number in zip(("capped_sum", "dropped_sum", "edges_sum"), summed.tolist(), strict=True):
                progress[key] += int(number)
        _check_finite(value, progress, epoch, b,
                      "samples: " + ", ".join(f"{run.train_sims[s].id} frame {t}" for s, t in batch), run.files.last)
        optimiser = self.state.optimiser
        for group in optimiser.param_groups:
            group["lr"] = learning_rate(cfg, progress["step"], progress["total_steps"])
        optimiser.zero_grad(set_to_none=True)
        loss.backward()
        optimiser.step()
        if self.state.average is not None:
            ema_update(self.state.average, run.simulator, float(cfg["ema_decay"]), progress["step"])
        return value

    def validated(self) -> tuple[LearnedSimulator, dict | None]:
        """The model validation rolls out, and the weights to load into it first (the average; None: its own)."""
        return self.run.validator, self.state.average

    def validates(self, epoch: int) -> bool:
        return epoch + 1 >= self.first_validated or epoch + 1 in self.snapshots

    def after_epoch(self, epoch: int) -> None:
        """On rank 0, after the epoch's record: fine-tuning follows the phase's end (also an early stop), and a
        learning-rate cycle's last epoch keeps a snapshot."""
        progress = self.state.progress
        if progress["finished"] and self.run.finetune is not None:
            progress.update(finished=False, epoch=self.end)
        if epoch + 1 in self.snapshots:
            self.run.files.write_snapshot(self.state, self.run.validator, self.snapshots)


class FinetunePhase:
    """Rollout fine-tuning (``train.finetune``; docs/surrogate.md, Rollout fine-tuning), the ``finetune.epochs``
    after the one-step ones: from the one-step phase's best validated weights, per step the normalised rollout MSE
    of ``finetune.batch_size`` train sims, ``L = sum |p_hat - p|^2 / (sum_t M_t sum_d sigma_{a,d}^2)`` with the
    gradient through the rollout (:func:`surrogate.rollout_loss.rollout_loss`), clipped to ``max_grad_norm``, a fresh
    optimiser at the rate of :func:`finetune_rate` and its own weight average (``finetune.ema_decay``). It never
    stops early; best.pt stays the best over both phases."""

    label = " (fine-tuning)"

    def __init__(self, run: Run, state: RunState, first_validated: int):
        self.run, self.state, self.cfg = run, state, run.finetune
        self.first_validated = first_validated
        self.start_epoch = int(run.train_cfg["epochs"])
        self.end = self.patience = self.start_epoch + int(self.cfg["epochs"])
        self.total_steps = int(self.cfg["epochs"]) * math.ceil(len(run.train_sims) / int(self.cfg["batch_size"]))
        self.lr = math.nan              # the rate of the latest step (history's lr column), from `begin`
        self.start_step = -1

    def begin(self) -> None:
        """Start the phase (from the one-step end in the state), or take up a resumed one: its first step's number
        and the rate of its latest step."""
        if self.start_step >= 0:
            return
        if self.state.tuned is None:
            self._start()
        progress = self.state.progress
        self.start_step = int(progress["finetune"]["start_step"])
        self.lr = finetune_rate(self.cfg, max(progress["step"] - self.start_step - 1, 0), self.total_steps)

    def _start(self) -> None:
        """Remember the one-step end (in the state), load the one-step best weights, and start a fresh optimiser and
        moving average."""
        state, progress, cfg, simulator = self.state, self.state.progress, self.cfg, self.run.simulator
        if state.best is None:
            raise ValueError("train.finetune: the one-step epochs left no validated weights to fine-tune")
        onestep = json.loads(json.dumps({k: v for k, v in progress.items() if k != "finetune"}))
        progress["finetune"] = {"start_epoch": progress["epoch"], "start_step": progress["step"], "onestep": onestep}
        progress["bad_epochs"] = 0
        simulator.load_state_dict({k: v.to(self.run.device) for k, v in state.best.items()})
        schedule = (f", warm-up over {cfg['warmup']} steps" if cfg.get("warmup") else "") + (
            f", decaying to {cfg['lr_final']:g}" if cfg.get("lr_final") is not None else "")
        log.info("fine-tuning (train.finetune): %d epochs of rollouts of %s frames, %d sims per step, lr %g%s, from "
                 "the one-step best (epoch %d, valid %.5g)", cfg["epochs"], cfg["frames"] or "all",
                 cfg["batch_size"], cfg["lr"], schedule, progress["best_epoch"], progress["best_mse"])
        average = ({k: v.detach().clone() for k, v in simulator.state_dict().items()}
                   if cfg["ema_decay"] is not None else None)
        state.tuned = Tuned(Tuned.new_optimiser(simulator, self.run.train_cfg, cfg), average, state.best)

    def batches(self, epoch: int) -> list[list[Sim]]:
        sims, size = self.run.train_sims, int(self.cfg["batch_size"])
        order = torch.randperm(len(sims), generator=generator(self.run.seed, epoch)).tolist()
        return [[sims[i] for i in order[b:b + size]] for b in range(0, len(order), size)]

    def step(self, epoch: int, b: int, batch: list[Sim]) -> float:
        """One optimiser step on the batch's rollout loss at the phase's rate for the step, the gradient clipped to
        ``max_grad_norm``, then the moving average; a non-finite loss stops the run before the step."""
        run, cfg, progress, tuned = self.run, self.cfg, self.state.progress, self.state.tuned
        with devices.autocast(run.simulator.lower.device, run.precision):
            loss = rollout_loss(run.simulator, batch, cfg["frames"], generator(run.seed, epoch, b, 2))
        value = float(loss.detach())
        _check_finite(value, progress, epoch, b, "the rollouts of " + ", ".join(sim.id for sim in batch),
                      run.files.last)
        self.lr = finetune_rate(cfg, progress["step"] - self.start_step, self.total_steps)
        for group in tuned.optimiser.param_groups:
            group["lr"] = self.lr
        tuned.optimiser.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(run.simulator.parameters(), float(cfg["max_grad_norm"]))
        tuned.optimiser.step()
        if tuned.average is not None:
            ema_update(tuned.average, run.simulator, float(cfg["ema_decay"]), progress["step"] - self.start_step)
        return value

    def validated(self) -> tuple[LearnedSimulator, dict | None]:
        """The moving average (loaded into the run's validator), or the weights themselves."""
        average = self.state.tuned.average
        return (self.run.simulator if average is None else self.run.validator), average

    def validates(self, epoch: int) -> bool:
        return epoch + 1 - self.start_epoch >= self.first_validated

    def after_epoch(self, epoch: int) -> None:
        """Nothing follows a fine-tuning epoch's record."""
