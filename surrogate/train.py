"""Training (article 5.4.3): Adam, L2 loss on the normalised acceleration of moving particles,
random-walk input noise, validation by rollout error, early stopping, resumable checkpoints.

Files in the output folder:

* ``best.pt``: weights with the lowest validation rollout MSE, with config and dataset stats
  (with ``ema_decay`` set, the exponential moving average of the weights is what is validated and kept);
* ``history.csv``: per epoch the mean training loss and the validation rollout MSE;
* ``last.pt``: the full training state (weights, optimiser, position in the epoch, history,
  best weights). It is written every ``checkpoint_every`` steps and at the end of every epoch.
  A run that finds an unfinished ``last.pt`` with the same model, data and training settings
  continues from it, with the same sample order and noise as an uninterrupted run; a finished or
  incompatible one is replaced by a fresh run.
"""

from __future__ import annotations

import json
import logging
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch
from tqdm import tqdm

from generators.atomic import atomic_path
from surrogate import checkpoint
from surrogate.errors import TrainingDiverged
from surrogate.noise import random_walk_position_noise
from surrogate.rollout import rollout, rollout_mse
from surrogate.samples import Sim, load_sim, sample_index
from surrogate.simulator import LearnedSimulator, build_graph, prune_isolated, stack_graphs

log = logging.getLogger("graphdem.train")

# Settings that may change between an interrupted run and its continuation.
_RESUMABLE_CHANGES = ("epochs", "patience", "checkpoint_every")


def _generator(*seeds: int) -> torch.Generator:
    return torch.Generator().manual_seed(int(np.random.SeedSequence(list(seeds)).generate_state(1)[0]))


def learning_rate(train_cfg: dict, step: int, total_steps: int) -> float:
    """Adam's learning rate at ``step``: constant ``lr`` (the article), or an exponential decay from
    ``lr`` to ``lr_final`` over the planned steps when ``lr_final`` is set."""
    lr, final = float(train_cfg["lr"]), train_cfg.get("lr_final")
    if final is None:
        return lr
    return lr * (float(final) / lr) ** min(step / max(total_steps, 1), 1.0)


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


def batch_loss(simulator: LearnedSimulator, sims: list[Sim], batch: list[tuple[int, int]], noise_std: float,
               generator: torch.Generator, mirror: bool = False, pushforward: float = 0.0,
               pushforward_steps: int = 1) -> torch.Tensor:
    """Mean squared error of the normalised acceleration over the moving particles of a batch.

    With ``mirror``, each sample is reflected in x (window and target together) with probability 1/2.
    With ``pushforward`` = p, each sample that has a frame before its window is, with probability p,
    a pushforward sample (Brandstetter et al. 2022): its history ends in the model's own predictions,
    made without gradient from the (noisy) window m frames earlier, and the target is the true next
    frame. m is drawn uniformly from 1 .. ``pushforward_steps`` (at most the frames there are before
    the window). The model so learns to correct the errors it makes itself in a rollout, at the cost
    of m extra forward passes per such sample.
    """
    k = simulator.history
    n = len(batch)
    flips = torch.rand(n, generator=generator) < 0.5 if mirror else torch.zeros(n, dtype=torch.bool)
    pushed = torch.rand(n, generator=generator) < pushforward if pushforward > 0 else torch.zeros(n, dtype=torch.bool)
    # m is drawn only for multi-step pushforward, so one-step runs keep their random stream unchanged
    steps = (torch.randint(1, pushforward_steps + 1, (n,), generator=generator) if pushforward_steps > 1
             else torch.ones(n, dtype=torch.long))
    windows, followings, sample_sims, truths = [], [], [], []
    for (s, t), flip, push, m in zip(batch, flips.tolist(), pushed.tolist(), steps.tolist(), strict=True):
        sim = sims[s]
        m = min(m, t - k + 1) if push else 0           # pushed steps need frames before the window
        frames = sim.position[t - k + 1 - m:t + 2]
        if flip:
            frames = mirror_x(frames, simulator.lower, simulator.upper)
        window = frames[:k]
        noise = random_walk_position_noise(k, window.shape[1], window.shape[2], noise_std, ~sim.kinematic, generator)
        windows.append(window + noise)
        # the target keeps the true next position relative to the noisy last one: the model learns to
        # correct the velocity noise, not to reproduce it (Sanchez-Gonzalez et al. 2020)
        followings.append(frames[-1] + noise[-1] if m == 0 else frames[-1])
        sample_sims.append(sim)
        truths.append(frames[k:k + m])                 # true frames of the pushed steps (kinematic part used)
    for j in range(max(len(f) for f in truths)):
        which = [i for i, f in enumerate(truths) if len(f) > j]
        earlier = stack_graphs([build_graph(windows[i], sample_sims[i].types, sample_sims[i].kinematic,
                                            simulator.radius, sample_sims[i].props) for i in which])
        with torch.no_grad():
            predicted = simulator.step(earlier, torch.cat([truths[i][j] for i in which]))
        sizes = [windows[i].shape[1] for i in which]
        for i, frame in zip(which, predicted.split(sizes), strict=True):
            windows[i] = torch.cat([windows[i][1:], frame.unsqueeze(0)])
    graphs, targets = [], []
    for window, following, sim in zip(windows, followings, sample_sims, strict=True):
        graphs.append(build_graph(window, sim.types, sim.kinematic, simulator.radius, sim.props))
        targets.append(simulator.target(window, following))
    # isolated wall particles cannot change a prediction: left out (exact), and only moving particles decoded
    graph, index = prune_isolated(stack_graphs(graphs))
    moving = (~graph.kinematic).nonzero().squeeze(1)
    prediction = simulator(graph, decode=moving)
    return ((prediction - torch.cat(targets)[index[moving]]) ** 2).mean()


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


def _settings(model_cfg: dict, train_cfg: dict, stats: dict, train_ids: list[str]) -> dict:
    fixed = {k: v for k, v in train_cfg.items() if k not in _RESUMABLE_CHANGES}
    return {"model": model_cfg, "train": fixed, "stats": stats, "train_sims": train_ids}


def train(stats_path: Path, splits_csv: Path, model_cfg: dict, train_cfg: dict, out_dir: Path,
          threads: int = 1, fresh: bool = False, max_steps: int | None = None, progress: bool = True) -> dict:
    """Train (or continue training) and write best.pt, last.pt and history.csv into ``out_dir``.

    ``max_steps`` stops after that many optimiser steps in this call, leaving an unfinished
    ``last.pt`` (used to test resuming; a real interruption behaves the same).
    """
    torch.set_num_threads(max(1, int(threads)))
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    stats = json.loads(Path(stats_path).read_text())
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
    valid_sims = [load_sim(p, stats, props) for p in valid_paths]
    k = int(model_cfg["history"])
    index = sample_index(train_sims, k)
    batch_size = int(train_cfg["batch_size"])
    n_batches = math.ceil(len(index) / batch_size)
    seed = int(train_cfg["seed"])
    settings = _settings(model_cfg, train_cfg, stats, [s.id for s in train_sims])

    torch.manual_seed(seed)
    simulator = LearnedSimulator(stats, model_cfg)
    optimiser = torch.optim.Adam(simulator.parameters(), lr=float(train_cfg["lr"]))
    state = {"epoch": 0, "batch": 0, "step": 0, "history": [], "best_mse": math.inf, "best_epoch": -1,
             "best_step": 0, "bad_epochs": 0, "finished": False, "loss_sum": 0.0, "loss_count": 0, "seconds": 0.0,
             # the learning-rate schedule is fixed when a run starts, so a resumed run follows it exactly
             "total_steps": int(train_cfg["epochs"]) * n_batches}
    best_weights = None
    decay = train_cfg.get("ema_decay")
    average = {k: v.detach().clone() for k, v in simulator.state_dict().items()} if decay is not None else None
    validator = LearnedSimulator(stats, model_cfg) if decay is not None else simulator
    last = out_dir / "last.pt"
    if last.exists() and not fresh:
        try:
            saved = checkpoint.load(last)
        except checkpoint.CheckpointError as exc:
            log.warning("ignoring %s: %s", last, exc)
            saved = None
        if saved is None:
            pass
        elif saved["json"].get("state", {}).get("finished"):
            log.info("%s is a finished run: starting a fresh one", last)
        elif saved["json"].get("settings") != json.loads(json.dumps(settings)):
            log.info("%s was trained with other settings or data: starting a fresh run", last)
        else:
            simulator.load_state_dict(saved["model"])
            optimiser.load_state_dict(saved["optimiser"])
            best_weights = saved.get("best_model")
            if average is not None:
                average = saved["average_model"]
            state = saved["json"]["state"]
            log.info("resuming from %s at epoch %d, batch %d, step %d", last, state["epoch"], state["batch"],
                     state["step"])

    def meta() -> dict:
        return {"model": model_cfg, "train": train_cfg, "stats": stats, "settings": settings, "state": state}

    def save_last() -> None:
        payload = {"model": simulator.state_dict(), "optimiser": optimiser.state_dict(), "json": meta()}
        if best_weights is not None:
            payload["best_model"] = best_weights
        if average is not None:
            payload["average_model"] = average
        checkpoint.save(last, payload)

    def save_outputs() -> None:
        history = pd.DataFrame(state["history"], columns=[
            "epoch", "step", "train_loss", "valid_rollout_mse", "best", "seconds", "lr"])
        with atomic_path(out_dir / "history.csv") as tmp:
            history.to_csv(tmp, index=False)
        if best_weights is not None:
            checkpoint.save(out_dir / "best.pt", {"model": best_weights, "json": {
                "model": model_cfg, "train": train_cfg, "stats": stats, "epoch": state["best_epoch"],
                "valid_rollout_mse": state["best_mse"], "step": state["best_step"]}})

    epochs, patience = int(train_cfg["epochs"]), int(train_cfg["patience"])
    every = int(train_cfg["checkpoint_every"])
    steps_this_call = 0
    simulator.train()
    clock = time.perf_counter()
    while state["epoch"] < epochs and not state["finished"]:
        epoch = state["epoch"]
        order = torch.randperm(len(index), generator=_generator(seed, epoch)).tolist()
        bar = tqdm(range(state["batch"], n_batches), desc=f"epoch {epoch + 1}/{epochs}", unit="batch",
                   disable=not progress, mininterval=2.0)
        for b in bar:
            batch = [index[i] for i in order[b * batch_size:(b + 1) * batch_size]]
            loss = batch_loss(simulator, train_sims, batch, float(train_cfg["noise_std"]),
                              _generator(seed, epoch, b, 1), mirror=bool(train_cfg["mirror"]),
                              pushforward=float(train_cfg["pushforward"]),
                              pushforward_steps=int(train_cfg["pushforward_steps"]))
            if not torch.isfinite(loss):
                samples = ", ".join(f"{train_sims[s].id} frame {t}" for s, t in batch)
                raise TrainingDiverged(
                    f"non-finite training loss ({loss.item()}) at step {state['step'] + 1} (epoch {epoch + 1}, "
                    f"batch {b + 1}) on samples: {samples}; the last good state is in {last}")
            for group in optimiser.param_groups:
                group["lr"] = learning_rate(train_cfg, state["step"], state["total_steps"])
            optimiser.zero_grad(set_to_none=True)
            loss.backward()
            optimiser.step()
            if average is not None:
                ema_update(average, simulator, float(decay), state["step"])
            state["step"] += 1
            state["batch"] = b + 1
            state["loss_sum"] += loss.item()
            state["loss_count"] += 1
            steps_this_call += 1
            bar.set_postfix(loss=f"{state['loss_sum'] / state['loss_count']:.4g}", refresh=False)
            if max_steps is not None and steps_this_call >= max_steps:
                state["seconds"] += time.perf_counter() - clock
                save_last()
                save_outputs()
                log.info("stopped after %d steps as asked (step %d); rerun to continue", max_steps, state["step"])
                return state
            if every and state["step"] % every == 0:
                state["seconds"] += time.perf_counter() - clock
                clock = time.perf_counter()
                save_last()
        bar.close()
        train_loss = state["loss_sum"] / max(state["loss_count"], 1)
        if average is not None:
            validator.load_state_dict(average)
        valid = validation_mse(validator, valid_sims)
        # the first epoch is the best so far even when its validation rollouts all blew up (+inf)
        improved = valid < state["best_mse"] or state["best_epoch"] == -1
        if improved:
            state["best_mse"], state["best_epoch"], state["bad_epochs"] = valid, epoch + 1, 0
            state["best_step"] = state["step"]
            best_weights = {k: v.detach().clone() for k, v in validator.state_dict().items()}
        else:
            state["bad_epochs"] += 1
        state["seconds"] += time.perf_counter() - clock
        clock = time.perf_counter()
        state["history"].append([epoch + 1, state["step"], train_loss, valid, improved, round(state["seconds"], 2),
                                 optimiser.param_groups[0]["lr"]])
        log.info("epoch %d: train loss %.5g, valid rollout MSE %.5g m^2%s", epoch + 1, train_loss, valid,
                 " (best)" if improved else "")
        state.update(epoch=epoch + 1, batch=0, loss_sum=0.0, loss_count=0)
        if state["bad_epochs"] >= patience:
            log.info("early stopping: no improvement for %d epochs", patience)
            state["finished"] = True
        if state["epoch"] >= epochs:
            state["finished"] = True
        save_outputs()          # outputs first: a kill in between never leaves a finished state without them
        save_last()
    if best_weights is None:
        raise ValueError(f"no epoch was completed (epochs = {epochs}): no best checkpoint")
    if not math.isfinite(state["best_mse"]):
        log.warning("every validation rollout blew up: best.pt holds epoch %d only because it came first",
                    state["best_epoch"])
    return state
