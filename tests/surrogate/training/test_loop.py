"""The end of an epoch (surrogate/training/loop.py): the validation error is the mean rollout MSE of the valid sims;
the epoch is recorded, the best kept, a worse epoch counted against the patience, an unvalidated one neither, and
the run finished by its patience or its last epoch."""

import math
import time

import numpy as np
import pytest

from surrogate.rollout import rollout, rollout_mse
from surrogate.samples import load_sim
from surrogate.training import loop, state

from .. import saved

HARDWARE = [1, 1, "cpu", "cpu"]


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    data = saved.untrained(tmp_path_factory.mktemp("loop"))
    sims = [load_sim(data["paths"][name], data["stats"]) for name in ("syn_02", "syn_03")]
    return data["simulator"], sims


def test_the_validation_error_is_the_mean_rollout_mse_of_the_valid_sims(data):
    simulator, sims = data
    k = simulator.history
    each = [rollout_mse(rollout(simulator, s).position, s.position.numpy(), ~s.kinematic.numpy(), k).mean()
            for s in sims]
    assert loop.validation_mse(simulator, sims) == pytest.approx(float(np.mean(each)), rel=1e-6)
    assert simulator.training                     # handed back for training
    simulator.eval()


def test_epochs_are_recorded_the_best_kept_and_the_patience_counted(data, monkeypatch):
    simulator, sims = data
    errors = iter([math.inf, 0.5, 0.7, 0.6, 0.9])    # the first epoch is the best so far, even blown up
    monkeypatch.setattr(loop, "validation_mse", lambda validator, valid: next(errors))
    progress = state.fresh_progress(100, capped=False)

    def end(validate=True, epochs=10):
        progress.update(step=progress["step"] + 5, loss_sum=2.0, loss_count=4)
        return loop.end_epoch(progress, simulator, None, sims, 2, epochs, 1e-3, time.perf_counter(), HARDWARE,
                              validate=validate)

    assert end() is not None and progress["best_epoch"] == 1                 # inf: best, as the first
    best = end()
    assert best is not None and (progress["best_mse"], progress["best_epoch"], progress["best_step"]) == (0.5, 2, 10)
    assert best.keys() == simulator.state_dict().keys()
    assert end(validate=False) is None and progress["bad_epochs"] == 0       # not validated: not counted
    assert end() is None and progress["bad_epochs"] == 1 and not progress["finished"]     # 0.7 > 0.5
    assert end() is None and progress["bad_epochs"] == 2 and progress["finished"]         # patience 2: stop
    rows = progress["history"]
    assert [r[0] for r in rows] == [1, 2, 3, 4, 5] and [r[1] for r in rows] == [5, 10, 15, 20, 25]
    assert all(r[2] == 0.5 for r in rows)                                    # train loss: 2.0 over 4 batches
    assert math.isnan(rows[2][3]) and [r[4] for r in rows] == [True, True, False, False, False]
    assert rows[0][-4:] == HARDWARE and (progress["batch"], progress["loss_count"]) == (0, 0)
    progress.update(finished=False, bad_epochs=0)
    end(epochs=7)                                                            # 0.9 at epoch 6 of 7: not yet the end
    assert not progress["finished"]
    errors = iter([0.1])
    monkeypatch.setattr(loop, "validation_mse", lambda validator, valid: next(errors))
    end(epochs=7)
    assert progress["finished"] and progress["best_epoch"] == 7               # the last epoch ends the run
