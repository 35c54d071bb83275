"""The generated tables' cells: a figure rounded as documented with its interval, a blown-up or undefined value
named, never a number; the markdown layout; the speed table of a tiny benchmark CSV."""

import math

import pandas as pd

from evaluation.doc_tables import kinds


def test_a_figure_is_rounded_with_its_interval_and_a_missing_one_is_named():
    acc = kinds.Quantity("acc_percent", "{metric}: Acc", kinds.PERCENT, " %", "acc")
    # one decimal, the interval from the acc_ci_* columns in the same rounding
    assert acc.cell({"acc_percent": 87.04, "acc_ci_low": 80.06, "acc_ci_high": 91.96}) == "87.0 % [80.1, 92.0]"
    assert acc.cell({"acc_percent": 87.04, "acc_ci_low": 80.06}) == "87.0 %"         # half an interval: none
    mse = kinds.Quantity("mse", "{metric}")
    assert mse.cell({"mse": 0.0123456}) == "0.0123"                                  # 3 significant digits
    assert mse.cell({"mse": math.nan, "n_blown_up": 2}) == kinds.BLOWN_UP
    assert mse.cell({"mse": math.nan, "n_blown_up": 0}) == kinds.UNDEFINED
    assert mse.cell({"mse": "", "n_blown_up": math.nan}) == kinds.UNDEFINED
    assert mse.cell(None) == ""                                                      # no row for this method


def test_markdown_escapes_a_pipe_and_finite_reads_numbers_only():
    assert kinds.markdown(["a", "b"], [["1", "x|y"]]) == "| a | b |\n| --- | --- |\n| 1 | x\\|y |"
    assert kinds.finite("2.5") and kinds.finite(3) and not kinds.finite(math.inf)
    assert not kinds.finite(None) and not kinds.finite("") and not kinds.finite(math.nan)


def test_the_speed_table_scales_to_milliseconds_and_names_blow_ups():
    table = pd.DataFrame([
        {"contender": "settle", "kind": "dem_settling", "seconds_per_frame": 1.0, "mse": math.nan,
         "speedup_vs_reference": math.nan, "stable": True, "main": False},
        {"contender": "dem", "kind": "dem", "seconds_per_frame": 0.25, "mse": 0.0, "speedup_vs_reference": 1.0,
         "stable": True, "main": False},
        {"contender": "gd", "kind": "surrogate", "seconds_per_frame": 0.0125, "mse": 1.5e-4,
         "speedup_vs_reference": 20.0, "stable": True, "main": True},
        {"contender": "coarse", "kind": "dem", "seconds_per_frame": math.nan, "mse": math.nan,
         "speedup_vs_reference": math.nan, "stable": False, "main": False}])
    rows = kinds.speed(table).splitlines()[2:]
    # 0.25 s = 250 ms; 0.0125 s = 12.5 ms and 0.25 / 0.0125 = 20x; the settling row is left out
    assert rows == ["| dem | dem | 250 | 0 | 1x |", "| gd (main) | surrogate | 12.5 | 0.00015 | 20x |",
                    f"| coarse | dem | {kinds.BLOWN_UP} | {kinds.BLOWN_UP} | {kinds.BLOWN_UP} |"]
