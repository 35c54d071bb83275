"""The phases of a training run (surrogate/training/phases.py), on stand-ins for the run: one-step epochs draw every
sample once in batches (or by activity), the same for the same epoch; which epochs are validated; fine-tuning
follows an early stop; a non-finite loss stops the run naming where; and fine-tuning's own epochs."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from surrogate.errors import TrainingDiverged
from surrogate.training import phases


def _one_step(index, activity=None, snapshots=(), first_validated=1, finetune=None, **cfg):
    run = SimpleNamespace(index=index, seed=5, finetune=finetune,
                          train_cfg={"epochs": 6, "patience": 3, "batch_size": 4, **cfg})
    state = SimpleNamespace(progress={"finished": False, "epoch": 0})
    return phases.OneStepPhase(run, state, None, activity, list(snapshots), first_validated)


def test_an_epoch_draws_every_sample_once_in_batches_the_same_for_the_same_epoch():
    index = [(s, t) for s in range(2) for t in range(3, 8)]            # 10 samples: batches of 4, 4 and 2
    phase = _one_step(index)
    batches = phase.batches(0)
    assert [len(b) for b in batches] == [4, 4, 2]
    assert sorted(sample for batch in batches for sample in batch) == index
    assert phase.batches(0) == batches and phase.batches(1) != batches
    assert (phase.end, phase.patience) == (6, 3)


def test_activity_draws_the_busy_samples_more_often():
    # sample 0 moves 99 times as much as each of the 9 others: weight 1 + 1 x 99 / 10.8 against 1 + 1 x 1 / 10.8
    activity = np.array([99.0] + [1.0] * 9)
    busy = phases.Activity(activity, weight=1.0, final=None, planned=10)
    drawn = [sample for epoch in range(40) for batch in _one_step(list(range(10)), busy).batches(epoch)
             for sample in batch]
    expected = (1 + 99 / 10.8) / ((1 + 99 / 10.8) + 9 * (1 + 1 / 10.8))
    assert drawn.count(0) / len(drawn) == pytest.approx(expected, abs=0.05)
    fading = phases.Activity(activity, weight=2.0, final=0.0, planned=5)
    assert [fading.weight_of(e) for e in range(5)] == [2.0, 1.5, 1.0, 0.5, 0.0]   # linear to the last epoch
    assert fading.draw_weights(4) is None                                      # weight 0: every sample once


def test_the_validated_epochs_and_what_follows_the_phase():
    phase = _one_step([(0, 3)], snapshots=[2], first_validated=5)
    assert [phase.validates(e) for e in range(6)] == [False, True, False, False, True, True]   # epoch 2: a snapshot
    tuned = _one_step([(0, 3)], finetune={"epochs": 2})
    tuned.state.progress.update(finished=True, epoch=3)                        # stopped early at epoch 3
    tuned.after_epoch(2)
    assert tuned.state.progress == {"finished": False, "epoch": 6}             # fine-tuning follows at epoch 6


def test_a_non_finite_loss_stops_the_run_naming_the_step_and_the_last_good_state(tmp_path):
    with pytest.raises(TrainingDiverged, match=r"non-finite training loss \(nan\) at step 8 \(epoch 2, batch 3\) on "
                                               r"samples: a frame 4; the last good state is in .*last.pt"):
        phases._check_finite(math.nan, {"step": 7}, 1, 2, "samples: a frame 4", tmp_path / "last.pt")
    phases._check_finite(0.5, {"step": 7}, 1, 2, "x", tmp_path / "last.pt")      # finite: nothing


def test_fine_tuning_s_epochs_follow_the_one_step_ones():
    sims = [SimpleNamespace(id=f"s{i}") for i in range(5)]
    run = SimpleNamespace(train_sims=sims, seed=1, finetune={"epochs": 3, "batch_size": 2},
                          train_cfg={"epochs": 4})
    phase = phases.FinetunePhase(run, SimpleNamespace(progress={}), first_validated=2)
    # 3 epochs after 4: the phase ends before epoch 7; 3 x ceil(5 / 2) = 9 steps; it never stops early
    assert (phase.start_epoch, phase.end, phase.patience, phase.total_steps) == (4, 7, 7, 9)
    assert [phase.validates(e) for e in range(4, 7)] == [False, True, True]
    batches = phase.batches(4)
    assert [len(b) for b in batches] == [2, 2, 1] and sorted(s.id for b in batches for s in b) == \
        [s.id for s in sims]
    assert phase.batches(4) == batches
