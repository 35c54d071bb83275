"""The optimisers of training, their learning rates and the epochs the schedules mark (docs/surrogate.md, Training):
Adam or AdamW, the one-step schedule (constant, exponential decay, warm restarts), the fine-tuning schedule (warm-up,
then decay), the exponential moving average of the weights, and the random generators of a run's draws."""

from __future__ import annotations

import numpy as np
import torch


def generator(*seeds: int) -> torch.Generator:
    """A generator seeded from ``seeds`` (the run's seed, the epoch, the batch, the phase): the same draws for the
    same place in a run, whether it ran in one go or was resumed."""
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


def ema_update(average: dict[str, torch.Tensor], model: torch.nn.Module, decay: float, step: int) -> None:
    """Exponential moving average of the weights, ``a <- d a + (1 - d) w``, with the usual warm-up
    ``d = min(decay, (1 + step) / (10 + step))`` so that the initial weights fade out quickly."""
    d = min(decay, (1 + step) / (10 + step))
    with torch.no_grad():
        for name, value in model.state_dict().items():
            if value.is_floating_point():
                average[name].lerp_(value, 1.0 - d)
