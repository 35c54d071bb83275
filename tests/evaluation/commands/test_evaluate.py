"""`graphdem evaluate` and `combine` (evaluation/commands/evaluate.py): the sims to score named one way only, one K
with stored rollouts, and tables stacked in order (of one layout, or with --union of several)."""

import pandas as pd
import pytest

from evaluation.commands import evaluate

from ...command_line import run


@pytest.mark.parametrize("argv, message", [
    ([], "give either --data .* or --splits"),
    (["--data", "a.h5", "--splits", "s.csv"], "give either --data .* or --splits"),
    (["--data", "a.h5", "--split", "auto"], "--split auto needs --splits"),
    (["--data", "a.h5", "--rollouts", "r", "--history", "3", "4"], "--rollouts holds rollouts of one K"),
])
def test_the_sims_and_the_protocols_must_be_named_one_way(tmp_path, argv, message):
    base = ["evaluate", "--checkpoint", str(tmp_path / "best.pt"), "--out", str(tmp_path / "m.csv")]
    history = [] if "--history" in argv else ["--history", "3"]
    with pytest.raises(SystemExit, match=message):
        run(evaluate.register, [*base, *history, *argv])
    assert not (tmp_path / "m.csv").exists()


def test_combine_stacks_tables_in_the_order_given(tmp_path, capsys):
    pd.DataFrame({"metric": ["rollout MSE"], "history": [3], "mse": [0.5]}).to_csv(tmp_path / "k3.csv", index=False)
    pd.DataFrame({"metric": ["rollout MSE"], "history": [6], "mse": [0.25]}).to_csv(tmp_path / "k6.csv", index=False)
    pd.DataFrame({"metric": ["Runout"], "history": [6], "acc_percent": [91.0]}).to_csv(tmp_path / "acc.csv",
                                                                                          index=False)
    out = tmp_path / "all.csv"
    run(evaluate.register, ["combine", "--tables", str(tmp_path / "k6.csv"), str(tmp_path / "k3.csv"),
                            "--out", str(out)])
    table = pd.read_csv(out)
    assert table.to_dict("list") == {"metric": ["rollout MSE"] * 2, "history": [6, 3], "mse": [0.25, 0.5]}
    assert f"{out}: 2 rows from 2 tables" in capsys.readouterr().out
    with pytest.raises(ValueError, match=r"acc.csv: columns \['metric', 'history', 'acc_percent'\] differ"):
        run(evaluate.register, ["combine", "--tables", str(tmp_path / "k3.csv"), str(tmp_path / "acc.csv"),
                                "--out", str(out)])
    run(evaluate.register, ["combine", "--union", "--tables", str(tmp_path / "k3.csv"), str(tmp_path / "acc.csv"),
                            "--out", str(out)])
    union = pd.read_csv(out)
    assert list(union["metric"]) == ["rollout MSE", "Runout"] and union["mse"].iloc[0] == 0.5
    assert union["mse"].isna().iloc[1] and union["acc_percent"].iloc[1] == 91.0


@pytest.mark.engine
def test_the_history_defaults_to_the_checkpoints(saved_checkpoint, tiny_dataset, tmp_path):
    import torch

    from surrogate import checkpoint
    from surrogate.simulator import LearnedSimulator
    _, sim, stats = saved_checkpoint
    for k in (4, 5):
        model = {**tiny_dataset["model"], "history": k}
        torch.manual_seed(0)
        meta = {"stats": stats, "model": model, "train": tiny_dataset["train"]}
        checkpoint.save(tmp_path / f"k{k}.pt", {"model": LearnedSimulator(stats, model).state_dict(), "json": meta})
    base = ["evaluate", "--checkpoint", str(tmp_path / "k4.pt"), "--data", str(sim), "--split", "test", "--no-progress"]
    run(evaluate.register, [*base, "--out", str(tmp_path / "default.csv")])
    run(evaluate.register, [*base, "--history", "4", "--out", str(tmp_path / "given.csv")])
    default, given = pd.read_csv(tmp_path / "default.csv"), pd.read_csv(tmp_path / "given.csv")
    assert set(default["history"]) == {4}                       # the checkpoint reads K = 4
    timed = default["unit"].eq("s")                            # the rollout's wall time differs run to run
    pd.testing.assert_frame_equal(default[~timed], given[~given["unit"].eq("s")])
    with pytest.raises(SystemExit, match=r"the checkpoints read different histories \[4, 5\]; give --history"):
        run(evaluate.register, ["evaluate", "--checkpoint", str(tmp_path / "k4.pt"), str(tmp_path / "k5.pt"),
                                "--data", str(sim), "--split", "test", "--out", str(tmp_path / "both.csv")])
