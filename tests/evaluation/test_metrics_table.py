"""The report's metrics table: every empty cell of metrics.csv is named n/a or undefined (with why), and the
numbers are the CSV's."""

import math
import re

import pandas as pd

from evaluation import metrics_table

NAN = math.nan
COLUMNS = ["scene", "method", "metric", "unit", "sim", "acc_percent", "acc_frames", "acc_pooled_percent", "mse",
           "mean_truth", "mean_prediction", "n_sims", "n_frames", "n_frames_left_out", "n_blown_up", "blown_up_sims",
           "split", "split_note", "history"]
ROWS = [
    ("slide", "graphdem", "rollout MSE", "m^2", "all", NAN, NAN, NAN, NAN, NAN, NAN, 1, 14, NAN, 1, "slide_0003",
     "test", NAN, 6),
    ("slide", "constant_velocity", "rollout MSE", "m^2", "all", NAN, NAN, NAN, 2.25, NAN, NAN, 1, 14, NAN, 0, NAN,
     "test", NAN, 6),
    ("slide", "graphdem", "Slide Num", "particles", "all", NAN, NAN, NAN, NAN, 18.5, NAN, 1, 14, 0, 1, "slide_0003",
     "test", NAN, 6),
    ("slide", "constant_velocity", "Slide Num", "particles", "all", NAN, NAN, NAN, NAN, NAN, NAN, 1, 14, 14, 0, NAN,
     "test", NAN, 6),
    ("slide", "constant_velocity", "Max Ht", "m", "all", 95.02, "1-14", 93.1, NAN, 34.66, 35.77, 1, 14, 0, 0, NAN,
     "test", NAN, 6),
    ("slide", "constant_velocity", "Dis", "m", "all", NAN, NAN, NAN, NAN, NAN, 28.26, 1, 14, 0, 0, NAN, "test", NAN,
     6),
    ("slide", "graphdem", "seconds per frame", "s", "all", NAN, NAN, NAN, NAN, NAN, 0.013, 1, NAN, NAN, NAN, NAN,
     "test", NAN, 6),
    ("slide", "graphdem", "rollout MSE", "m^2", "slide_0003", NAN, NAN, NAN, NAN, NAN, NAN, 1, 14, NAN, 1,
     "slide_0003", "test", NAN, 6),
]
HEADINGS = ["method", "metric", "sim", *(c for c in metrics_table.COLUMNS if c in COLUMNS), "why"]


def cells(page: str) -> dict[tuple[str, str, str], list[str]]:
    """(method, metric, sim) -> the texts of the row's cells, tags removed."""
    out = {}
    for row in re.findall(r"<tr>(.*?)</tr>", page, re.S):
        texts = [re.sub(r"<[^>]+>", " ", c).split() for c in re.findall(r"<td[^>]*>(.*?)</td>", row, re.S)]
        texts = [" ".join(t) for t in texts]
        if texts:
            out[(texts[0], texts[1].split(" (")[0], texts[2])] = dict(zip(HEADINGS, texts, strict=True))
    return out


def values(row: dict[str, str], *columns: str) -> list[str]:
    return [row[c] for c in columns]


def test_every_empty_cell_says_n_a_or_undefined_and_why(tmp_path):
    csv = tmp_path / "metrics.csv"
    pd.DataFrame(ROWS, columns=COLUMNS).to_csv(csv, index=False)
    before = csv.read_bytes()
    page = metrics_table.write(csv, tmp_path / "metrics.html", "slide: metrics").read_text()
    assert csv.read_bytes() == before                       # the CSV is only read
    assert "nan" not in re.sub(r"<[^>]+>", " ", page).lower().split()
    rows = cells(page)
    value_columns = ["acc_percent", "mse", "mean_truth", "mean_prediction"]
    blown = rows[("graphdem", "rollout MSE", "all")]
    # the rollout MSE's one figure is its MSE: no mean prediction beside it
    assert values(blown, "acc_percent", "mse", "mean_prediction") == ["n/a", "undefined", "n/a"]
    assert blown["why"] == "1 rollout(s) blew up: slide_0003" and blown["n_blown_up"] == "1 slide_0003"
    baseline = rows[("constant_velocity", "rollout MSE", "all")]
    assert values(baseline, *value_columns) == ["n/a", "2.25", "n/a", "n/a"] and baseline["why"] == ""
    assert values(baseline, "acc_frames", "acc_pooled_percent") == ["n/a", "n/a"]
    flagged = rows[("graphdem", "Slide Num", "all")]        # truth defined, the rollout blew up
    assert values(flagged, *value_columns) == ["undefined", "n/a", "18.5", "undefined"] and "blew up" in flagged["why"]
    assert flagged["acc_pooled_percent"] == "undefined"
    no_truth = rows[("constant_velocity", "Slide Num", "all")]
    assert no_truth["acc_percent"] == "undefined"
    assert "truth is zero or undefined in every scored frame" in no_truth["why"]
    assert "undefined in all 14 scored frames" in no_truth["why"]
    max_ht = rows[("constant_velocity", "Max Ht", "all")]
    assert values(max_ht, *value_columns) == ["95.02", "n/a", "34.66", "35.77"]
    assert values(max_ht, "acc_frames", "acc_pooled_percent") == ["1-14", "93.1"]
    dis = rows[("constant_velocity", "Dis", "all")]          # compares prediction with truth: no Acc, no truth
    assert values(dis, *value_columns) == ["n/a", "n/a", "n/a", "28.26"] and dis["why"] == ""
    timing = rows[("graphdem", "seconds per frame", "all")]
    assert values(timing, "acc_percent", "acc_frames", "acc_pooled_percent", "mse", "mean_truth", "mean_prediction",
                  "n_sims", "n_frames", "n_frames_left_out", "n_blown_up") == \
        ["n/a", "n/a", "n/a", "n/a", "n/a", "0.013", "1", "n/a", "n/a", "n/a"]
    assert rows[("graphdem", "rollout MSE", "slide_0003")]["mse"] == "undefined"
    # each metric named with the CSV's unit (the timing's is in no metric module's registry), the MSE's in its heading
    assert {"Max Ht (m)", "Slide Num (particles)", "seconds per frame (s)", "rollout MSE"} <= \
        {label for _, label, _ in re.findall(r"<tr><td[^>]*>(.*?)</td><td[^>]*>(.*?)</td><td[^>]*>(.*?)</td>", page)}
    assert "MSE (m²)" in page
    assert "<h2>Per sim</h2>" in page and "split test" in page and "K = 6" in page


def test_a_one_tau_frame_set_is_shown_as_the_tau_not_a_float(tmp_path):
    """The meteorite's ci window reaches only tau = 5 of Table 2's set: the column then holds '5' alone, which a
    plain CSV read beside an empty cell would turn into 5.0."""
    csv = tmp_path / "metrics.csv"
    row = ("meteorite", "graphdem", "Imp Dep", "m", "all", 91.5, "5", 90.0, NAN, 2.0, 1.83, 1, 5, 0, 0, NAN, "test",
           NAN, 6)
    mse = ("meteorite", "graphdem", "rollout MSE", "m^2", "all", NAN, NAN, NAN, 0.5, NAN, NAN, 1, 5, NAN, 0, NAN,
           "test", NAN, 6)                          # no frame set: the column also holds an empty cell
    pd.DataFrame([row, mse], columns=COLUMNS).to_csv(csv, index=False)
    page = metrics_table.write(csv, tmp_path / "metrics.html", "meteorite: metrics").read_text()
    assert cells(page)[("graphdem", "Imp Dep", "all")]["acc_frames"] == "5"


def test_the_yardsticks_figures_show_their_bootstrap_interval_and_their_csv_numbers(tmp_path):
    from evaluation.summary import summarise
    from tests.evaluation.test_summary import INTERVALS, rows
    steps = pd.DataFrame(rows("graphdem", "Max Ht", {"a": 0.1, "b": 0.3}, spread=0.25)
                         + rows("constant_velocity", "Max Ht", {"a": 0.8, "b": 0.8}, spread=0.25)
                         + rows("dem_ensemble", "Max Ht", {"a": 0.2, "b": 0.4}, spread=0.25))
    csv = tmp_path / "metrics.csv"
    table = summarise(steps, intervals=INTERVALS, units={"Max Ht": "m"})
    table.to_csv(csv, index=False)
    page = metrics_table.write(csv, tmp_path / "metrics.html", "slide").read_text()
    shown = ["method", "metric", "sim", *metrics_table.shown(table), "why"]
    found = {}
    for row in re.findall(r"<tr>(.*?)</tr>", page, re.S):
        texts = [" ".join(re.sub(r"<[^>]+>", " ", c).split()) for c in re.findall(r"<td[^>]*>(.*?)</td>", row, re.S)]
        if texts:
            found[texts[0]] = dict(zip(shown, texts, strict=True))
    model = table.set_index("method").loc["graphdem"]
    assert found["graphdem"]["skill"] == (f"{model['skill']:.4g} [{model['skill_ci_low']:.4g}, "
                                          f"{model['skill_ci_high']:.4g}]")
    assert found["graphdem"]["error_in_spreads"] == f"{model['error_in_spreads']:.4g}" == "0.8"
    assert found["constant_velocity"]["skill"].startswith("0 ")


def test_without_a_dem_ensemble_its_figures_are_n_a_and_say_why(tmp_path):
    """User data and the public benchmarks have no DEM ensemble: its figures are n/a (not undefined), the skill
    against constant velocity stays a number."""
    from evaluation.summary import summarise
    from tests.evaluation.test_summary import INTERVALS, rows
    steps = pd.DataFrame(rows("graphdem", "Max Ht", {"a": 0.1, "b": 0.3})        # no members: no spread
                         + rows("constant_velocity", "Max Ht", {"a": 0.8, "b": 0.8}))
    csv = tmp_path / "metrics.csv"
    table = summarise(steps, intervals=INTERVALS, units={"Max Ht": "m"})
    assert table["error_in_spreads"].isna().all() and table["vs_members"].isna().all()
    table.to_csv(csv, index=False)
    page = metrics_table.write(csv, tmp_path / "metrics.html", "mine").read_text()
    shown = ["method", "metric", "sim", *metrics_table.shown(table), "why"]
    row = next(dict(zip(shown, texts, strict=True)) for texts in (
        [" ".join(re.sub(r"<[^>]+>", " ", c).split()) for c in re.findall(r"<td[^>]*>(.*?)</td>", r, re.S)]
        for r in re.findall(r"<tr>(.*?)</tr>", page, re.S)) if texts and texts[0] == "graphdem")
    assert row["error_in_spreads"] == row["vs_members"] == "n/a" and row["why"] == ""
    assert row["skill"].split()[0] == f"{table.set_index('method').at['graphdem', 'skill']:.4g}"
    assert "no DEM ensemble in this evaluation" in page
