"""A training run's state (surrogate/training/state.py): what a continuation must share with the run it continues,
the counters of a fresh run, the one-step end of a fine-tuned run, history.csv, and how a run continues from its
last.pt: fresh where there is none or it was trained otherwise, resumed exactly where it stopped."""

import math

import pandas as pd
import torch

from surrogate.simulator import LearnedSimulator
from surrogate.training import state
from surrogate.training.schedules import make_optimiser

from .. import synthetic

TRAIN = {**synthetic.TRAIN, "epochs": 4, "patience": 2, "checkpoint_every": 10, "validate_last": 2}


def test_a_continuation_may_change_only_the_run_s_length_patience_and_checkpoints():
    fixed = state.settings({"history": 3}, {**TRAIN, "finetune": {"epochs": 2}}, {"dim": 2}, ["a", "b"])
    assert fixed["train"] == {k: v for k, v in TRAIN.items()
                              if k not in ("epochs", "patience", "checkpoint_every", "validate_last")}
    assert fixed["model"] == {"history": 3} and fixed["stats"] == {"dim": 2} and fixed["train_sims"] == ["a", "b"]
    assert state.settings({}, {**TRAIN, "epochs": 40, "patience": 9}, {}, []) == state.settings({}, TRAIN, {}, [])
    assert state.settings({}, {**TRAIN, "lr": 0.5}, {}, []) != state.settings({}, TRAIN, {}, [])
    assert state.tuning({"epochs": 2, "lr": 1e-4, "validate_last": 1}) == {"epochs": 2, "lr": 1e-4}
    assert state.tuning(None) is None


def test_a_fresh_run_s_counters_and_a_fine_tuned_run_s_one_step_end():
    fresh = state.fresh_progress(120, capped=True)
    assert (fresh["epoch"], fresh["step"], fresh["best_epoch"], fresh["total_steps"]) == (0, 0, -1, 120)
    assert math.isinf(fresh["best_mse"]) and fresh["capped_sum"] == 0
    assert "capped_sum" not in state.fresh_progress(120, capped=False)
    onestep = {**fresh, "epoch": 4, "finished": True}
    saved = {"json": {"state": {**onestep, "epoch": 6, "finetune": {"onestep": onestep}}}, "onestep_best": {"w": 1},
             "best_model": {"w": 2}}
    assert state.one_step_end(saved, finished=False) == ({**onestep, "finished": False}, {"w": 1})
    plain = {"json": {"state": onestep}, "best_model": {"w": 2}}
    assert state.one_step_end(plain, finished=True) == (onestep, {"w": 2})


def _run(tmp_path, data, train_cfg=TRAIN, seed=0):
    torch.manual_seed(seed)
    simulator = LearnedSimulator(data["stats"], synthetic.MODEL)
    progress = state.fresh_progress(40, capped=False)
    files = state.RunFiles(tmp_path, synthetic.MODEL, train_cfg, data["stats"],
                           state.settings(synthetic.MODEL, train_cfg, data["stats"], ["syn_00"]), None, False)
    return state.RunState(progress, simulator, make_optimiser(simulator.parameters(), train_cfg), None), files


def test_a_run_resumes_from_its_last_pt_exactly_and_starts_afresh_when_trained_otherwise(tmp_path):
    data = synthetic.build(tmp_path / "data")
    run, files = _run(tmp_path, data)
    run.progress.update(epoch=2, batch=3, step=23, history=[[1, 11, 0.5, 0.25, True, 1.0, 1e-3, 1, 1, "cpu", "cpu"],
                                                             [2, 22, 0.4, 0.3, False, 2.0, 1e-3, 1, 1, "cpu", "cpu"]],
                        best_mse=0.25, best_epoch=1)
    files.write_last(run)
    files.write_outputs(run)
    history = pd.read_csv(tmp_path / "history.csv")
    assert list(history.columns) == list(state.HISTORY_COLUMNS) and list(history["valid_rollout_mse"]) == [0.25, 0.3]
    again, files = _run(tmp_path, data, seed=1)                    # other initial weights, the same settings
    assert again.restore(files.read_last(fresh=False), files, torch.device("cpu")) == "resumed"
    assert (again.progress["epoch"], again.progress["batch"], again.progress["step"]) == (2, 3, 23)
    for name, value in run.simulator.state_dict().items():
        torch.testing.assert_close(again.simulator.state_dict()[name], value)
    other, files = _run(tmp_path, data, {**TRAIN, "lr": 0.5})
    assert other.restore(files.read_last(fresh=False), files, torch.device("cpu")) == "fresh"
    assert other.progress["step"] == 0
    assert files.read_last(fresh=True) is None
    assert again.restore(None, files, torch.device("cpu")) == "fresh"
