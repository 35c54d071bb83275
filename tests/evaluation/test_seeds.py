"""The spread over training seeds: mean, sample std and range of every metric, by hand; a blown-up seed is never
dropped from the mean."""

import math

import pandas as pd
import pytest

from evaluation import seeds


def _table(mse: float, acc: float, pooled: float) -> pd.DataFrame:
    return pd.DataFrame([
        {"scene": "slide", "method": "graphdem", "metric": "rollout MSE", "sim": "all", "mse": mse,
         "mean_prediction": math.nan, "acc_percent": math.nan, "acc_pooled_percent": math.nan},
        {"scene": "slide", "method": "graphdem", "metric": "rollout MSE", "sim": "slide_0003", "mse": 99.0,
         "mean_prediction": math.nan, "acc_percent": math.nan, "acc_pooled_percent": math.nan},
        {"scene": "slide", "method": "graphdem", "metric": "Max Ht", "sim": "all", "mse": math.nan,
         "mean_prediction": 40.0 + acc / 100, "acc_percent": acc, "acc_pooled_percent": pooled},
        {"scene": "slide", "method": "constant_velocity", "metric": "Max Ht", "sim": "all", "mse": math.nan,
         "mean_prediction": 41.0, "acc_percent": 95.0, "acc_pooled_percent": 94.0},
    ])


def test_mean_std_range_and_each_seeds_value():
    table = seeds.spread({0: _table(1.0, 96.0, 90.0), 1: _table(2.0, 98.0, 92.0), 2: _table(3.0, 97.0, 91.0)})
    row = table[(table["metric"] == "rollout MSE") & (table["column"] == "mse")].iloc[0]
    assert (row["mean"], row["std"], row["min"], row["max"], row["n_seeds"]) == (2.0, 1.0, 1.0, 3.0, 3)
    assert row["values"] == "0:1 1:2 2:3"
    acc = table[(table["method"] == "graphdem") & (table["metric"] == "Max Ht")].set_index("column")
    assert acc.at["acc_percent", "mean"] == pytest.approx(97.0) and acc.at["acc_percent", "std"] == pytest.approx(1.0)
    assert acc.at["acc_pooled_percent", "mean"] == pytest.approx(91.0)
    baseline = table[(table["method"] == "constant_velocity") & (table["column"] == "acc_percent")].iloc[0]
    assert baseline["std"] == 0.0 and baseline["mean"] == 95.0
    # the per-sim rows are not seeds' summaries; the rollout MSE's one figure is its mse (its mean_prediction empty)
    assert list(table.loc[table["metric"] == "rollout MSE", "column"]) == ["mse"]


def test_a_seed_that_blew_up_makes_the_mean_undefined_not_better():
    table = seeds.spread({0: _table(1.0, 96.0, 90.0), 1: _table(math.nan, math.nan, math.nan)})
    row = table[(table["metric"] == "rollout MSE") & (table["column"] == "mse")].iloc[0]
    assert math.isnan(row["mean"]) and row["n_seeds"] == 2 and row["values"] == "0:1 1:nan"


def test_read_refuses_mismatched_or_repeated_seeds(tmp_path):
    path = tmp_path / "m.csv"
    _table(1.0, 96.0, 90.0).to_csv(path, index=False)
    with pytest.raises(ValueError, match="2 metrics tables for 1 seeds"):
        seeds.read([path, path], [0])
    with pytest.raises(ValueError, match="repeat a seed"):
        seeds.read([path, path], [1, 1])
    assert list(seeds.read([path], [4])) == [4]
