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


def test_the_runout_table_gives_each_fit_over_the_sims_at_rest_and_their_longest_rest():
    sims = [{"sim": f"s{k}", "friction": mu, "at_rest": rest, "rest_time_scaled": t, "column_diameters": 25.0}
            for k, (mu, rest, t) in enumerate([(0.3, True, 5.04), (0.3, False, math.nan), (0.6, True, 7.25)])]
    fit = {"sim": "fit", "linear_prefactor": 1.064, "power_prefactor": 1.2756, "power_exponent": 1.0324,
           "height_exponent": 0.2356, "n_small": 2, "n_large": 1, "at_rest": math.nan, "rest_time_scaled": math.nan,
           "column_diameters": math.nan}
    table = pd.DataFrame(sims + [{**fit, "friction": "all"}, {**fit, "friction": "0.3", "power_prefactor": math.nan},
                                 {**fit, "friction": "0.6"}])
    rows = kinds.runout(table).splitlines()
    assert rows[0].startswith("| friction | column width (mean diameters) | sims at rest (fitted) | small a: ")
    assert rows[2:] == ["| all | 25 | 2 of 3 | 1.06 a (2 sims) | 1.28 a^1.03 (1 sims) | 0.24 | 7.2 |",
                        f"| 0.3 | 25 | 1 of 2 | 1.06 a (2 sims) | {kinds.UNDEFINED} (1 sims) | 0.24 | 5.0 |",
                        "| 0.6 | 25 | 1 of 1 | 1.06 a (2 sims) | 1.28 a^1.03 (1 sims) | 0.24 | 7.2 |"]


def test_a_sources_pattern_may_name_the_tables_subject(tmp_path):
    from evaluation import doc_tables
    for name in ("a", "b"):
        (tmp_path / f"{name}.py").write_text(name)
    kind = kinds.Kind("k", "{subject}/x.csv", (), ("{subject}.py",), str)
    assert doc_tables.code_hash(kind, tmp_path, "a") != doc_tables.code_hash(kind, tmp_path, "b")
    (tmp_path / "b.py").write_text("changed")         # b's change leaves a's hash as it was
    assert doc_tables.code_hash(kind, tmp_path, "a") == doc_tables.code_hash(kinds.Kind(
        "k", "{subject}/x.csv", (), ("a.py",), str), tmp_path)
