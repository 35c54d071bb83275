"""The random generators of a run's draws (surrogate/training/schedules.py; its rates, snapshots and weight
average: tests/surrogate/test_train.py): the same place in a run draws the same numbers, another place others."""

import torch

from surrogate.training import schedules


def test_the_same_seeds_draw_the_same_numbers_and_any_other_seeds_others():
    def draws(*seeds):
        return torch.rand(8, generator=schedules.generator(*seeds))

    torch.testing.assert_close(draws(0, 3, 5, 1), draws(0, 3, 5, 1))        # a resumed run draws as it would have
    others = [draws(1, 3, 5, 1), draws(0, 4, 5, 1), draws(0, 3, 6, 1), draws(0, 3, 5, 2), draws(0, 5, 3, 1),
              draws(0, 3, 5)]
    for other in others:                                                     # each seed, and their order, counts
        assert not torch.equal(other, draws(0, 3, 5, 1))


def test_the_one_step_rate_decays_from_lr_to_lr_final_over_the_planned_steps():
    cfg = {"lr": 1e-3, "lr_final": 1e-5}
    # exponential in between: a quarter of the way, lr (lr_final / lr)^(1/4) = 1e-3 x 0.01^0.25
    rates = [schedules.learning_rate(cfg, s, 100) for s in (0, 25, 100)]
    assert rates[0] == 1e-3 and abs(rates[1] - 1e-3 * 0.01 ** 0.25) < 1e-15 and abs(rates[2] - 1e-5) < 1e-18
