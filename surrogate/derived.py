"""Training defaults derived from the data (docs/surrogate.md, "Derived defaults"), each by a stated rule.

``train.noise_std: auto``: the random-walk input noise (std of the last input velocity, m per frame) is
``train.noise_ratio`` times the train split's acceleration std (m per frame^2, root mean square over the axes,
``stats.json``). The ratio carries what was measured on the public benchmarks: 0.1 m of noise at an
acceleration std of 1.61 m per frame^2 (ratio 0.062) beat 0.05 m and 3e-4 m on both sets and matched
0.15 m (docs/benchmarks.md). A noise of the size of the per-frame velocity change is what a rollout's own
one-step errors look like to the next step, so a fixed length would be no noise at all on one scene and
swamp the motion on another.

``train.ema_decay: auto``: the moving average of the weights spans ``train.ema_epochs`` epochs of optimiser
steps, ``decay = 1 - 1 / max(1, ema_epochs x batches per epoch)``. On the benchmarks ``0.999`` (1000 steps)
was measured at 1575 batches per epoch, so 0.63 epochs; a scene of 150 batches per epoch gets 0.989.

``connectivity_radius: auto`` (user data, docs/user-data.md): the graph radius R is ``connectivity_diameters``
times the mean diameter of the train split's moving particles, the way the scenes state theirs (2.5 mean diameters
at the default scale of the slide, the meteorite and the collapse). The dataset stage derives it, and stats.json
records the number and the rule's inputs under ``derived``.
"""

from __future__ import annotations

import math

AUTO = "auto"


def noise_std(stats: dict, ratio: float) -> float:
    """``ratio`` x the root mean square over axes of the train split's acceleration std (``stats.json``)."""
    if not ratio > 0:
        raise ValueError(f"train.noise_ratio is {ratio!r}; allowed: a number > 0")
    std = [float(s) for s in stats["acceleration_std"]]
    return float(ratio * math.sqrt(sum(s * s for s in std) / len(std)))


def ema_decay(batches_per_epoch: int, epochs: float) -> float:
    """The decay whose average spans ``epochs`` epochs of ``batches_per_epoch`` optimiser steps."""
    if not epochs > 0:
        raise ValueError(f"train.ema_epochs is {epochs!r}; allowed: a number > 0")
    return 1.0 - 1.0 / max(1.0, float(epochs) * int(batches_per_epoch))


def connectivity_radius(mean_radius: float, diameters: float) -> float:
    """``diameters`` x the mean diameter (2 x ``mean_radius``) of the train split's moving particles (m)."""
    if not diameters > 0:
        raise ValueError(f"connectivity_diameters is {diameters!r}; allowed: a number > 0")
    if not mean_radius > 0:
        raise ValueError(f"the mean radius of the moving particles is {mean_radius!r}; allowed: a number > 0 (the "
                         f"train split needs moving particles)")
    return float(diameters * 2.0 * mean_radius)


def resolve(train_cfg: dict, stats: dict, batches_per_epoch: int) -> dict:
    """``train_cfg`` with every ``auto`` value replaced by its derived number (the checkpoint records both: the
    number in its train settings, the rule's inputs under ``derived``)."""
    out, derived = dict(train_cfg), {}
    if train_cfg.get("noise_std") == AUTO:
        out["noise_std"] = noise_std(stats, float(train_cfg["noise_ratio"]))
        derived["noise_std"] = {"rule": "noise_ratio x rms acceleration_std", "noise_ratio": train_cfg["noise_ratio"],
                                "acceleration_std": list(stats["acceleration_std"])}
    if train_cfg.get("ema_decay") == AUTO:
        out["ema_decay"] = ema_decay(batches_per_epoch, float(train_cfg["ema_epochs"]))
        derived["ema_decay"] = {"rule": "1 - 1 / (ema_epochs x batches per epoch)",
                                "ema_epochs": train_cfg["ema_epochs"], "batches_per_epoch": int(batches_per_epoch)}
    if derived:
        out["derived"] = derived
    return out
