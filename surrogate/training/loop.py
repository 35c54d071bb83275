"""The epoch loop of a training run (docs/surrogate.md, Training): the epochs of its phases in turn, each epoch's
optimiser steps, then on rank 0 its validation by rollout error, its record in the history, early stopping and the
checkpoints (best.pt, last.pt every ``checkpoint_every`` steps and at each epoch's end)."""

from __future__ import annotations

import logging
import math
import time

import numpy as np
import torch
from tqdm import tqdm

from surrogate import distributed
from surrogate.rollout import rollout, rollout_mse
from surrogate.samples import Sim
from surrogate.simulator import LearnedSimulator
from surrogate.training.phases import Phase, Run
from surrogate.training.state import RunState

log = logging.getLogger("graphdem.train")


def run_epochs(run: Run, state: RunState, phases: list[Phase], max_steps: int | None) -> bool:
    """Train the epochs of ``phases`` (each ends before its epoch ``end``) from where ``state`` stands, until the
    last phase's end or early stopping; False where ``max_steps`` optimiser steps in this call stopped it first,
    with an unfinished last.pt (resuming after it continues as an uninterrupted run would)."""
    total_epochs, every = phases[-1].end, int(run.train_cfg["checkpoint_every"])
    steps_this_call = 0
    clock = time.perf_counter()
    while state.progress["epoch"] < total_epochs and not state.progress["finished"]:
        epoch = state.progress["epoch"]
        phase = next(phase for phase in phases if epoch < phase.end)
        phase.begin()
        batches = phase.batches(epoch)
        bar = tqdm(range(state.progress["batch"], len(batches)), desc=f"epoch {epoch + 1}/{total_epochs}"
                   + phase.label, unit="batch", disable=not run.show_progress, mininterval=2.0)
        for b in bar:
            value = phase.step(epoch, b, batches[b])
            progress = state.progress
            progress["step"] += 1
            progress["batch"] = b + 1
            progress["loss_sum"] += value
            progress["loss_count"] += 1
            steps_this_call += 1
            bar.set_postfix(loss=f"{progress['loss_sum'] / progress['loss_count']:.4g}", refresh=False)
            if max_steps is not None and steps_this_call >= max_steps:
                progress["seconds"] += time.perf_counter() - clock
                if run.world.main:
                    run.files.write_last(state)
                    run.files.write_outputs(state)
                distributed.barrier(run.world)
                log.info("stopped after %d steps as asked (step %d); rerun to continue", max_steps, progress["step"])
                return False
            if every and progress["step"] % every == 0:
                progress["seconds"] += time.perf_counter() - clock
                clock = time.perf_counter()
                if run.world.main:
                    run.files.write_last(state)
        bar.close()
        if run.world.main:
            validator, average = phase.validated()
            state.best = end_epoch(state.progress, validator, average, run.valid_sims, phase.patience, phase.end,
                                   phase.lr, clock, run.hardware, validate=phase.validates(epoch)) or state.best
            phase.after_epoch(epoch)
            run.files.write_outputs(state)     # outputs first: a kill in between never leaves a finished state
            run.files.write_last(state)        # without them
        state.progress = distributed.from_main(state.progress, run.world)   # the others wait for rank 0's validation
        clock = time.perf_counter()
    return True


def end_epoch(state: dict, validator: LearnedSimulator, average: dict | None, valid_sims: list[Sim], patience: int,
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
