import math

import numpy as np
import pytest
import torch

from surrogate.noise import random_walk_position_noise


def test_noise_is_a_random_walk_that_ends_at_the_configured_std():
    k, n, std = 6, 200_000, 3e-4
    moving = torch.ones(n, dtype=torch.bool)
    noise = random_walk_position_noise(k, n, 2, std, moving, torch.Generator().manual_seed(0), torch.float64)
    assert torch.all(noise[0] == 0)                                     # the oldest frame is exact
    velocity_noise = (noise[1:] - noise[:-1]).numpy()                   # [K-1, N, D]
    increments = np.diff(velocity_noise, axis=0, prepend=0.0)
    # independent increments of std sigma / sqrt(K-1) ...
    np.testing.assert_allclose(increments.std(axis=(1, 2)), std / math.sqrt(k - 1), rtol=0.01)
    corr = np.corrcoef(increments[0].ravel(), increments[1].ravel())[0, 1]
    assert abs(corr) < 0.01
    # ... whose cumulative effect on the last velocity has exactly the configured std
    assert velocity_noise[-1].std() == pytest.approx(std, rel=0.01)
    # positions integrate the velocity walk: at frame j, increment l enters (j - l + 1) times, so
    # Var = sigma^2 / (K-1) * sum_{c=1..j} c^2
    expected = std * np.sqrt([sum(c * c for c in range(1, j + 1)) / (k - 1) for j in range(k)])
    np.testing.assert_allclose(noise.numpy().std(axis=(1, 2))[1:], expected[1:], rtol=0.01)


def test_kinematic_particles_get_no_noise():
    moving = torch.tensor([True, False, True, False])
    noise = random_walk_position_noise(5, 4, 3, 1.0, moving, torch.Generator().manual_seed(1))
    assert torch.all(noise[:, ~moving] == 0) and torch.all(noise[1:, moving] != 0)


def test_history_must_carry_a_velocity():
    with pytest.raises(ValueError, match="at least 2 frames"):
        random_walk_position_noise(1, 3, 2, 1.0, torch.ones(3, dtype=torch.bool))
