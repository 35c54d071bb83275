"""`graphdem seeds` (evaluation/commands/seeds.py): two seeds' metrics tables give each metric's mean, sample
standard deviation and range, written and printed."""

import math

import pandas as pd
import pytest

from evaluation.commands import seeds

from ...command_line import run


def _metrics(path, mse, acc):
    rows = [{"scene": "slide", "method": "graphdem", "metric": "rollout MSE", "history": 6, "sim": "all", "mse": mse,
             "acc_percent": math.nan, "mean_prediction": math.nan},
            {"scene": "slide", "method": "graphdem", "metric": "Runout", "history": 6, "sim": "all", "mse": math.nan,
             "acc_percent": acc, "mean_prediction": 1.0},
            {"scene": "slide", "method": "graphdem", "metric": "Runout", "history": 6, "sim": "slide_0001",
             "mse": math.nan, "acc_percent": 0.0, "mean_prediction": 9.0}]      # a sim's row: not combined
    pd.DataFrame(rows).to_csv(path, index=False)


def test_two_seeds_give_each_metric_s_mean_and_spread(tmp_path, capsys):
    _metrics(tmp_path / "s0.csv", 1.0, 80.0)
    _metrics(tmp_path / "s1.csv", 3.0, 90.0)
    out = tmp_path / "seeds.csv"
    run(seeds.register, ["seeds", "--metrics", str(tmp_path / "s0.csv"), str(tmp_path / "s1.csv"),
                         "--seeds", "0", "1", "--out", str(out)])
    table = pd.read_csv(out).set_index(["metric", "column"])
    # MSE 1 and 3: mean 2, sample std sqrt(((1 - 2)^2 + (3 - 2)^2) / 1) = sqrt(2); Acc 80 and 90: 85, sqrt(50)
    mse = table.loc[("rollout MSE", "mse")]
    assert (mse["mean"], mse["std"], mse["min"], mse["max"], mse["n_seeds"]) == (2.0, pytest.approx(math.sqrt(2)),
                                                                                  1.0, 3.0, 2)
    assert mse["values"] == "0:1 1:3"
    acc = table.loc[("Runout", "acc_percent")]
    assert (acc["mean"], acc["std"]) == (85.0, pytest.approx(math.sqrt(50)))
    assert ("rollout MSE", "mean_prediction") not in table.index          # the MSE's figure is its mse alone
    assert "2 +- 1.4 (1 .. 3, 2 seeds)" in capsys.readouterr().out


def test_one_table_per_seed(tmp_path):
    _metrics(tmp_path / "s0.csv", 1.0, 80.0)
    with pytest.raises(ValueError, match="1 metrics tables for 2 seeds"):
        run(seeds.register, ["seeds", "--metrics", str(tmp_path / "s0.csv"), "--seeds", "0", "1",
                             "--out", str(tmp_path / "o.csv")])
