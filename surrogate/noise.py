"""Random-walk noise on the input history (article 5.4.3, after Sanchez-Gonzalez et al. 2020).

The article injects N(0, sigma_v^2) "random-walk" noise, sigma_v = 3e-4, into every training
sample. We follow the convention of the Graph Network-based Simulator that the article builds on:

* the K-1 input velocities receive independent increments of standard deviation
  ``sigma / sqrt(K-1)``, accumulated along the history, so the noise on the *last* velocity has
  standard deviation exactly ``sigma`` (a random walk that ends at the configured std);
* positions receive the running sum of the velocity noise (zero on the oldest frame), so the noisy
  history is still an exact finite-difference history of noisy positions (eq. 1);
* kinematic particles get no noise: their positions come from the data.

``sigma`` is in the dataset's length units per frame (metres for our scenes).
"""

from __future__ import annotations

import math

import torch


def random_walk_position_noise(history: int, n: int, dim: int, std: float, moving: torch.Tensor,
                               generator: torch.Generator | None = None,
                               dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """Position noise ``[K, N, D]`` for a history of K frames; zero for kinematic particles."""
    if history < 2:
        raise ValueError(f"history must be at least 2 frames to carry a velocity, got {history}")
    steps = torch.randn(history - 1, n, dim, generator=generator, dtype=dtype) * (std / math.sqrt(history - 1))
    velocity_noise = torch.cumsum(steps, dim=0)                      # [K-1, N, D], std sigma at the end
    position_noise = torch.cat([torch.zeros(1, n, dim, dtype=dtype), torch.cumsum(velocity_noise, dim=0)])
    return position_noise * moving.to(dtype).view(1, n, 1)
