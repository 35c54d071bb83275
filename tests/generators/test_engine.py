"""What every engine run shares: the perturbed packing of a chaos rerun."""

import numpy as np

from generators import dem, engine


def test_perturbation_moves_only_moving_particles_by_the_given_radii_and_repeats():
    rng = np.random.default_rng(0)
    packing = dem.Particles(rng.uniform(0, 1, (400, 2)), rng.uniform(0.01, 0.02, 400), np.r_[np.zeros(100, int),
                                                                                             np.ones(300, int)])
    a = engine.perturbed(packing, (0,), 1e-3, seed=7)
    b = engine.perturbed(packing, (0,), 1e-3, seed=7)
    np.testing.assert_array_equal(a.x, b.x)                               # seeded by the row's seed
    np.testing.assert_array_equal(a.x[:100], packing.x[:100])             # kinematic particles stay put
    step = (a.x[100:] - packing.x[100:]) / packing.radius[100:, None]
    assert abs(step.std() - 1e-3) < 1e-4 and abs(step.mean()) < 2e-4       # N(0, 1e-3 radii) per axis
    assert not np.array_equal(engine.perturbed(packing, (0,), 1e-3, seed=8).x, a.x)
