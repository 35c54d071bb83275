"""A training run's state and its files (docs/surrogate.md, Files and resuming): :class:`RunState` is everything
``last.pt`` holds and the rules by which a run continues from it; :class:`RunFiles` writes it and the outputs made
from it (``history.csv``, ``best.pt``, ``snapshot_<c>.pt``)."""

from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from generators.atomic import atomic_path
from surrogate import checkpoint
from surrogate.simulator import LearnedSimulator
from surrogate.training.schedules import make_optimiser

log = logging.getLogger("graphdem.train")

# history.csv: per epoch its record, then where it ran (a benchmark card's training cost needs both)
HISTORY_COLUMNS = ("epoch", "step", "train_loss", "valid_rollout_mse", "best", "seconds", "lr",
                   "threads", "processes", "device", "device_name")
# the columns a neighbour cap adds to history.csv (sums over the epoch's training graphs)
CAP_HISTORY = ["capped_receivers", "dropped_edges", "edges_before_cap"]
# Settings that may change between an interrupted run and its continuation.
_RESUMABLE_CHANGES = ("epochs", "patience", "checkpoint_every", "validate_last")


def settings(model_cfg: dict, train_cfg: dict, stats: dict, train_ids: list[str]) -> dict:
    """What a run's last.pt must share with the run that continues it: everything but the keys that may change
    (``epochs``, ``patience``, ``checkpoint_every``) and the fine-tuning phase, which a continued run redoes when
    it changed."""
    fixed = {k: v for k, v in train_cfg.items() if k not in _RESUMABLE_CHANGES and k != "finetune"}
    return {"model": model_cfg, "train": fixed, "stats": stats, "train_sims": train_ids}


def tuning(finetune: dict | None) -> dict | None:
    """The fine-tuning settings that shape its weights: all but ``validate_last``, which only skips validations."""
    return None if finetune is None else {k: v for k, v in finetune.items() if k != "validate_last"}


def fresh_progress(total_steps: int, capped: bool) -> dict:
    """The counters of a run that has not begun (``total_steps``: the one-step steps planned; ``capped``: the model
    has a neighbour cap, whose cuts are summed over each epoch's training graphs)."""
    progress = {"epoch": 0, "batch": 0, "step": 0, "history": [], "best_mse": math.inf, "best_epoch": -1,
                "best_step": 0, "bad_epochs": 0, "finished": False, "loss_sum": 0.0, "loss_count": 0,
                "seconds": 0.0,
                # the learning-rate schedule is fixed when a run starts, so a resumed run follows it exactly
                "total_steps": total_steps}
    if capped:
        progress.update(capped_sum=0, dropped_sum=0, edges_sum=0)
    return progress


def one_step_end(saved: dict, finished: bool) -> tuple[dict, dict | None]:
    """A saved run's state and best weights at the end of its one-step epochs (its fine-tuning phase undone)."""
    state = saved["json"]["state"]
    if "finetune" in state:
        return {**state["finetune"]["onestep"], "finished": finished}, saved["onestep_best"]
    return {**state, "finished": finished}, saved.get("best_model")


@dataclass
class RunFiles:
    """A run's folder (``out_dir``) and what its files carry besides the state: the configs (``train_cfg`` with
    its derived values), the dataset stats, the ``settings`` a continuation must share, the fine-tuning settings
    (None: none) and whether the model has a neighbour cap (history.csv's extra columns)."""

    folder: Path
    model_cfg: dict
    train_cfg: dict
    stats: dict
    settings: dict
    finetune: dict | None
    capped: bool

    @property
    def last(self) -> Path:
        return self.folder / "last.pt"

    def read_last(self, fresh: bool) -> dict | None:
        """The folder's last.pt, or None: there is none, ``fresh`` asks to ignore it, or it is unreadable."""
        if not self.last.exists() or fresh:
            return None
        try:
            return checkpoint.load(self.last)
        except checkpoint.CheckpointError as exc:
            log.warning("ignoring %s: %s", self.last, exc)
            return None

    def write_last(self, state: RunState) -> None:
        meta = {"model": self.model_cfg, "train": self.train_cfg, "stats": self.stats, "settings": self.settings,
                "state": state.progress}
        checkpoint.save(self.last, state.payload(meta))

    def write_outputs(self, state: RunState) -> None:
        """history.csv, and best.pt once an epoch was validated."""
        progress = state.progress
        # a run resumed from a last.pt written before the hardware columns has shorter rows: blank there (such a
        # run has no neighbour cap: the cap is newer than the hardware columns)
        columns = list(HISTORY_COLUMNS) + (CAP_HISTORY if self.capped else [])
        history = pd.DataFrame([row[:len(columns)] + [None] * (len(columns) - len(row))
                                for row in progress["history"]], columns=columns)
        if self.finetune is not None:              # an epoch past the one-step ones is a fine-tuning epoch
            start = progress.get("finetune", {}).get("start_epoch", int(self.train_cfg["epochs"]))
            history["phase"] = np.where(history["epoch"] > start, "finetune", "onestep")
        with atomic_path(self.folder / "history.csv") as tmp:
            history.to_csv(tmp, index=False)
        if state.best is not None:
            self._weights("best.pt", state.best, progress["best_epoch"], progress["best_mse"], progress["best_step"])

    def write_snapshot(self, state: RunState, validator: LearnedSimulator, snapshots: list[int]) -> None:
        """The validated weights at the end of a learning-rate cycle (the epoch just closed ends cycle c of
        ``snapshots``' epochs): ``snapshot_<c>.pt``, in best.pt's format."""
        progress = state.progress
        self._weights(f"snapshot_{snapshots.index(progress['epoch']) + 1}.pt",
                      {k: v.detach().to("cpu", copy=True) for k, v in validator.state_dict().items()},
                      progress["epoch"], progress["history"][-1][3], progress["step"])

    def _weights(self, name: str, weights: dict, epoch: int, mse: float, step: int) -> None:
        checkpoint.save(self.folder / name, {"model": weights, "json": {
            "model": self.model_cfg, "train": self.train_cfg, "stats": self.stats, "epoch": epoch,
            "valid_rollout_mse": mse, "step": step}})


@dataclass
class Tuned:
    """What last.pt keeps of the fine-tuning phase: its optimiser, the moving average of its weights (None without
    ``finetune.ema_decay``) and the one-step phase's best weights, which a changed fine-tuning is redone from."""

    optimiser: torch.optim.Optimizer
    average: dict | None
    onestep_best: dict

    @staticmethod
    def new_optimiser(simulator: LearnedSimulator, train_cfg: dict, cfg: dict) -> torch.optim.Optimizer:
        """The phase's optimiser: the one-step phase's kind (Adam, or AdamW with its weight decay) at ``cfg['lr']``."""
        return make_optimiser(simulator.parameters(), {**train_cfg, "lr": cfg["lr"]})

    @classmethod
    def restore(cls, saved: dict, simulator: LearnedSimulator, train_cfg: dict, cfg: dict,
                device: torch.device) -> Tuned:
        optimiser = cls.new_optimiser(simulator, train_cfg, cfg)
        optimiser.load_state_dict(saved["finetune_optimiser"])
        average = saved.get("finetune_average")
        average = None if average is None else {k: v.to(device) for k, v in average.items()}
        return cls(optimiser, average, saved["onestep_best"])


@dataclass
class RunState:
    """Everything a run's last.pt holds, and how a run continues from it.

    last.pt: ``model`` (the weights being trained), ``optimiser`` (the one-step phase's, kept while fine-tuning),
    ``json`` (the configs, the stats, the settings a continuation must share and ``state``, the counters:
    :attr:`progress`), ``best_model`` (the best validated weights, once there are), ``average_model`` (the
    one-step weight average, with ``ema_decay``) and, once fine-tuning began, ``finetune_optimiser``,
    ``finetune_average`` and ``onestep_best`` (:class:`Tuned`). ``progress`` is also what :func:`train` returns."""

    progress: dict
    simulator: LearnedSimulator
    optimiser: torch.optim.Optimizer
    average: dict | None
    best: dict | None = None
    tuned: Tuned | None = None

    def payload(self, meta: dict) -> dict:
        """last.pt's contents, with ``meta`` as its JSON."""
        payload = {"model": self.simulator.state_dict(), "optimiser": self.optimiser.state_dict(), "json": meta}
        if self.best is not None:
            payload["best_model"] = self.best
        if self.average is not None:
            payload["average_model"] = self.average
        if self.tuned is not None:
            payload.update(finetune_optimiser=self.tuned.optimiser.state_dict(),
                           finetune_average=self.tuned.average, onestep_best=self.tuned.onestep_best)
        return payload

    def restore(self, saved: dict | None, files: RunFiles, device: torch.device) -> str:
        """Continue from ``saved`` (the folder's last.pt, None where there is none to read) as far as its settings
        allow, and say how: ``fresh`` (none, other settings or data, or a finished run: this fresh state stays),
        ``rolled_back`` (a run whose fine-tuning was removed: it ends where its one-step epochs ended),
        ``refinetune`` (its one-step epochs are done and its fine-tuning, none or another, is not this one: the
        phase starts again from their end) or ``resumed`` (where it was interrupted, exactly)."""
        if saved is None:
            return "fresh"
        last, finetune = files.last, files.finetune
        saved_state = saved["json"].get("state", {})
        same_finetune = tuning(saved["json"].get("train", {}).get("finetune")) == tuning(json.loads(
            json.dumps(finetune)))
        if saved["json"].get("settings") != json.loads(json.dumps(files.settings)):
            log.info("%s was trained with other settings or data: starting a fresh run", last)
            return "fresh"
        if "finetune" in saved_state and finetune is None:
            self.progress, self.best = one_step_end(saved, finished=True)
            self.simulator.load_state_dict(saved["model"])
            log.info("%s: train.finetune was removed; the run ends where its one-step epochs ended (epoch %d)",
                     last, self.progress["epoch"])
            return "rolled_back"
        if (finetune is not None and (not same_finetune or "finetune" not in saved_state)
                and (saved_state.get("finished") or "finetune" in saved_state)
                and saved_state.get("total_steps") == self.progress["total_steps"]):   # this run's planned steps
            self.progress, self.best = one_step_end(saved, finished=False)
            self.progress["epoch"] = int(files.train_cfg["epochs"])   # also after an early stop: fine-tuning next
            self._load_one_step(saved, device)
            log.info("%s: its %d one-step epochs are done; fine-tuning (train.finetune) starts from their end",
                     last, len(self.progress["history"]))
            return "refinetune"
        if saved_state.get("finished"):
            log.info("%s is a finished run: starting a fresh one", last)
            return "fresh"
        self._load_one_step(saved, device)
        self.best = saved.get("best_model")
        self.progress = saved["json"]["state"]
        if "finetune" in self.progress:
            self.tuned = Tuned.restore(saved, self.simulator, files.train_cfg, finetune, device)
        log.info("resuming from %s at epoch %d, batch %d, step %d", last, self.progress["epoch"],
                 self.progress["batch"], self.progress["step"])
        return "resumed"

    def _load_one_step(self, saved: dict, device: torch.device) -> None:
        """The saved weights, the one-step optimiser and (with ``ema_decay``) the one-step weight average."""
        self.simulator.load_state_dict(saved["model"])
        self.optimiser.load_state_dict(saved["optimiser"])
        if self.average is not None:
            self.average = {k: v.to(device) for k, v in saved["average_model"].items()}
