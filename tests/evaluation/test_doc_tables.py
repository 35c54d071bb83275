"""`graphdem tables`: the docs' results tables written from tiny CSVs of the real layout, the text outside the
markers kept byte for byte, the stamps, and --check flagging a table whose producing code changed."""

import dataclasses
import math
import re

import pandas as pd
import pytest

from evaluation import doc_tables
from evaluation.doc_tables import blocks, kinds
from graphdem import cli

NAN = math.nan
# metrics.csv's columns before the evaluation gained skill, change errors, intervals and units (such a CSV still
# renders), then the provenance evaluate adds to every row (the config itself lies beside the CSV: config_sidecar)
COLUMNS = ["scene", "method", "metric", "sim", "acc_percent", "acc_frames", "acc_pooled_percent", "mse",
           "mean_truth", "mean_prediction", "n_sims", "n_frames", "n_frames_left_out", "n_blown_up", "blown_up_sims",
           "split", "split_note", "history", "checkpoint", "checkpoint_sha", "config_sha", "code_version"]
PROVENANCE = ("test", NAN, 6, "best.pt", "15792618e549", "001234567890", "0.1.0+abc123def456")
ROWS = [  # method, metric, sim, acc, acc_frames, pooled, mse, truth, prediction, sims, frames, left out, blown, which
    ("graphdem", "rollout MSE", "all", NAN, NAN, NAN, 0.54812, NAN, NAN, 2, 28, NAN, 0, ""),
    ("constant_velocity", "rollout MSE", "all", NAN, NAN, NAN, 1.88049, NAN, NAN, 2, 28, NAN, 0, ""),
    ("dem_ensemble", "rollout MSE", "all", NAN, NAN, NAN, 0.44714, NAN, NAN, 2, 28, NAN, 0, ""),
    ("graphdem", "Max Ht", "all", 99.2173, "1-14", 97.93, NAN, 38.0412, 37.7, 2, 28, 0, 0, ""),
    ("constant_velocity", "Max Ht", "all", NAN, NAN, NAN, NAN, 38.0412, NAN, 2, 28, 0, 1, "slide_0003"),
    ("graphdem", "Dis", "all", NAN, NAN, NAN, NAN, NAN, 55.3149, 2, 28, 0, 0, ""),
    ("graphdem", "seconds per frame", "all", NAN, NAN, NAN, NAN, NAN, 0.0131, 2, NAN, NAN, NAN, ""),
    ("graphdem", "rollout MSE", "slide_0003", NAN, NAN, NAN, 0.61, NAN, NAN, 1, 14, NAN, 0, ""),
]
# some of the columns the evaluation gained: skill, errors in ensemble spreads and bootstrap intervals
_ = NAN
NEW = {  # one value per row of ROWS
    "mse_ci_low": [0.41, 1.5, 0.3, _, _, _, _, _], "mse_ci_high": [0.69, 2.2, 0.6, _, _, _, _, _],
    "acc_ci_low": [_, _, _, 98.51, _, _, _, _], "acc_ci_high": [_, _, _, 99.73, _, _, _, _],
    "skill": [0.7085, 0.0, _, 0.5812, _, _, _, _],
    "skill_ci_low": [0.6, _, _, 0.4112, _, _, _, _], "skill_ci_high": [0.8, _, _, 0.7713, _, _, _, _],
    "error_in_spreads": [1.21, 2.05, 1.0, _, _, _, _, _]}
BEFORE = "# Results\r\n\r\nText before, kept as it is.  \n\n```\n<!-- table: slide-speed -->\n```\n"
AFTER = "\nText after. <!-- table: inline-metrics --> is text, not a marker.\n"
EMPTY = "<!-- table: slide-metrics -->\n<!-- /table: slide-metrics -->\n"


def metrics_csv(path, new: bool = False):
    table = pd.DataFrame([("slide", *row[:3], *row[3:], *PROVENANCE) for row in ROWS], columns=COLUMNS)
    if new:
        table = table.assign(**NEW)
    path.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(path, index=False)
    return table


@pytest.fixture
def repo(tmp_path):
    """A repository with docs/results.md holding one empty block, its metrics.csv and a producing file."""
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "results.md").write_bytes((BEFORE + EMPTY + AFTER).encode())
    metrics_csv(tmp_path / "results" / "slide" / "metrics.csv")
    code = tmp_path / "code"
    (code / "producer").mkdir(parents=True)
    (code / "producer" / "summary.py").write_text("def summarise():\n    return 1\n")
    fake = {"metrics": dataclasses.replace(kinds.KINDS["metrics"], sources=("producer/*.py",))}
    return {"root": tmp_path, "doc": tmp_path / "docs" / "results.md", "kinds": fake, "code": code}


def write(repo) -> list:
    outcomes = doc_tables.plan(repo["root"], kinds=repo["kinds"], code_root=repo["code"])
    doc_tables.write(outcomes)
    return outcomes


def check(repo):
    return doc_tables.check(repo["root"], kinds=repo["kinds"], code_root=repo["code"])


def generated(path) -> tuple[blocks.Stamp, dict[str, list[str]]]:
    """The stamp of a file's first block and its table: label -> cells."""
    block = blocks.find(path, path.read_text())[0]
    stamp, table = blocks.split_body(block.body)
    rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in table.splitlines()[2:]]
    return stamp, {row[0]: row[1:] for row in rows}


def test_write_changes_only_the_text_between_the_markers(repo):
    outcomes = write(repo)
    assert [(o.block.name, o.changed) for o in outcomes] == [("slide-metrics", True)]
    text = repo["doc"].read_bytes()
    assert text.startswith((BEFORE + "<!-- table: slide-metrics -->\n").encode())
    assert text.endswith(("<!-- /table: slide-metrics -->\n" + AFTER).encode())
    stamp, rows = generated(repo["doc"])
    assert stamp is not None and "rollout MSE (m²)" in rows


def test_the_numbers_are_the_csvs_rounded_as_documented(repo):
    write(repo)
    _, rows = generated(repo["doc"])
    table = doc_tables.blocks.split_body(blocks.find(repo["doc"], repo["doc"].read_text())[0].body)[1]
    assert table.splitlines()[0] == "| metric | DEM truth (mean) | Graph-DEM | constant velocity | DEM ensemble |"
    assert rows["rollout MSE (m²)"] == ["", "0.548", "1.88", "0.447"]
    assert rows["Max Ht: Acc"] == ["38", "99.2 %", kinds.BLOWN_UP, ""]         # blown up: named, never a number
    assert rows["Dis"] == ["", "55.3", "", ""]
    assert not any(label.startswith("seconds per frame") for label in rows)    # how it ran: the speed table's
    assert not any("skill" in label or "[" in " ".join(cells) for label, cells in rows.items())   # absent: no rows


def test_new_columns_are_shown_with_their_intervals_where_the_csv_has_them(repo):
    metrics_csv(repo["root"] / "results" / "slide" / "metrics.csv", new=True)
    write(repo)
    _, rows = generated(repo["doc"])
    assert rows["rollout MSE (m²)"] == ["", "0.548 [0.41, 0.69]", "1.88 [1.5, 2.2]", "0.447 [0.3, 0.6]"]
    assert rows["Max Ht: Acc"][1] == "99.2 % [98.5, 99.7]"
    assert rows["rollout MSE: skill"] == ["", "0.71 [0.60, 0.80]", "0.00", kinds.UNDEFINED]
    assert rows["Max Ht: skill"] == ["", "0.58 [0.41, 0.77]", kinds.BLOWN_UP, ""]
    assert rows["rollout MSE: error in ensemble spreads"] == ["", "1.21", "2.05", "1.00"]
    assert "Max Ht: error in ensemble spreads" not in rows and "Dis: skill" not in rows


def per_step(method: str, metric: str, errors: dict[str, float], member: int = 0) -> list[dict]:
    """metrics_per_step.csv rows of two sims over three frames: the prediction off the truth by ``errors[sim]``."""
    out = []
    for sim, error in errors.items():
        for tau in (1, 2, 3):
            truth = NAN if metric == "rollout MSE" else 10.0 + tau
            out.append({"scene": "slide", "method": method, "metric": metric, "sim": sim, "member": member,
                        "tau": tau, "frame": 5 + tau, "time": 0.1 * tau, "truth": truth, "blown_up": False,
                        "prediction": error if metric == "rollout MSE" else truth + error * (-1) ** tau,
                        "truth_start": 10.0, "spread": 0.25, "diameter": 0.5})
    return out


def test_a_metrics_csv_of_the_evaluations_own_summary(repo):
    from evaluation.evaluate import summarise
    from evaluation.metrics.scores import Intervals
    steps = [row for metric in ("rollout MSE", "Max Ht") for row in
             per_step("graphdem", metric, {"a": 0.1, "b": 0.3})
             + per_step("constant_velocity", metric, {"a": 0.8, "b": 0.8})
             + per_step("dem_ensemble", metric, {"a": 0.2, "b": 0.2})
             + per_step("dem_ensemble", metric, {"a": 0.4, "b": 0.4}, member=1)]
    table = summarise(pd.DataFrame(steps), intervals=Intervals(samples=200, level=0.95, seed=0), units={"Max Ht": "m"})
    csv = repo["root"] / "results" / "slide" / "metrics.csv"
    table.assign(**dict(zip(COLUMNS[-7:], PROVENANCE, strict=True))).to_csv(csv, index=False)
    write(repo)
    _, rows = generated(repo["doc"])
    read = pd.read_csv(csv).query("sim == 'all'").set_index(["metric", "method"])
    methods = ["graphdem", "constant_velocity", "dem_ensemble"]

    def cells(metric, column, interval, spec, unit=""):
        return [f"{read.loc[(metric, m), column]:{spec}}{unit} [{read.loc[(metric, m), interval + '_ci_low']:{spec}}, "
                f"{read.loc[(metric, m), interval + '_ci_high']:{spec}}]" for m in methods]

    assert rows["rollout MSE (m²)"] == ["", *cells("rollout MSE", "mse", "mse", kinds.NUMBER)]
    assert rows["Max Ht: Acc"] == ["12", *cells("Max Ht", "acc_percent", "acc", kinds.PERCENT, " %")]
    assert rows["Max Ht: change error"] == ["", *cells("Max Ht", "change_error", "change_error", kinds.NUMBER)]
    assert rows["Max Ht: skill"] == ["", *cells("Max Ht", "skill", "skill", kinds.SCORE)]
    assert rows["rollout MSE: error in ensemble spreads"] == [
        "", *(f"{read.loc[('rollout MSE', m), 'error_in_spreads']:{kinds.SCORE}}" for m in methods)]


def test_the_stamp_names_the_csv_its_config_sha_commit_and_the_producing_code(repo):
    write(repo)
    stamp, _ = generated(repo["doc"])
    csv = repo["root"] / "results" / "slide" / "metrics.csv"
    assert stamp.source == "results/slide/metrics.csv"
    assert stamp.config == "001234567890"                 # read as text: the leading zeros kept
    assert stamp.commit == "abc123def456"
    assert stamp.code == doc_tables.code_hash(repo["kinds"]["metrics"], repo["code"])
    assert re.fullmatch(r"[0-9a-f]{12}", stamp.data) and re.fullmatch(r"\d{4}-\d\d-\d\d", stamp.date)
    assert re.search(r", \d+ logical CPUs$", stamp.machine)
    assert blocks.Stamp.parse(stamp.text()) == stamp
    table = pd.read_csv(csv).drop(columns=["config_sha", "code_version"])
    table.to_csv(csv, index=False)                         # a CSV that records neither
    write(repo)
    stamp, _ = generated(repo["doc"])
    assert stamp.config == blocks.NOT_RECORDED and stamp.commit.endswith(blocks.HEAD)


def test_writing_twice_gives_the_same_bytes(repo):
    write(repo)
    first = repo["doc"].read_bytes()
    outcomes = write(repo)
    assert repo["doc"].read_bytes() == first
    assert [o.changed for o in outcomes] == [False]


def test_check_flags_a_table_after_a_producing_file_changed(repo):
    assert check(repo) == ([], [f"{blocks.find(repo['doc'], repo['doc'].read_text())[0].where}: slide-metrics: "
                                f"never generated (no stamp); graphdem tables --write fills it from "
                                f"results/slide/metrics.csv"])
    write(repo)
    assert check(repo) == ([], [])
    (repo["code"] / "producer" / "summary.py").write_text("def summarise():\n    return 2\n")
    stale, never = check(repo)
    assert never == [] and len(stale) == 1 and "slide-metrics: stale" in stale[0]
    (repo["code"] / "producer" / "new.py").write_text("")  # a new producing file changes the hash too
    assert len(check(repo)[0]) == 1


def test_write_does_not_clear_staleness_until_the_csv_is_made_again(repo):
    write(repo)
    (repo["code"] / "producer" / "summary.py").write_text("def summarise():\n    return 2\n")
    outcomes = write(repo)                                  # the same CSV: still the old code's numbers
    assert [(o.changed, o.stale) for o in outcomes] == [(False, True)]
    assert len(check(repo)[0]) == 1
    csv = repo["root"] / "results" / "slide" / "metrics.csv"
    pd.read_csv(csv).assign(code_version="0.1.0+fedcba987654").to_csv(csv, index=False)   # the stage rerun
    outcomes = write(repo)
    assert [(o.changed, o.stale) for o in outcomes] == [(True, False)]
    assert check(repo) == ([], []) and generated(repo["doc"])[0].commit == "fedcba987654"


def test_a_missing_csv_leaves_the_table_as_it_is_and_is_named(repo, capsys, monkeypatch):
    write(repo)
    before = repo["doc"].read_bytes()
    (repo["root"] / "results" / "slide" / "metrics.csv").unlink()
    monkeypatch.setattr(doc_tables, "KINDS", repo["kinds"])
    monkeypatch.setattr(doc_tables, "CODE_ROOT", repo["code"])
    assert cli.main(["tables", "--root", str(repo["root"]), "--write", str(repo["doc"])]) == 0
    assert repo["doc"].read_bytes() == before
    out = capsys.readouterr().out
    assert out.startswith("not regenerated: ") and out.rstrip().endswith("slide-metrics: results/slide/metrics.csv "
                                                                         "missing")


def test_bad_input_is_named(repo):
    doc = repo["doc"]
    doc.write_text("a\n<!-- table: slide-metrics -->\nb\n")
    with pytest.raises(blocks.MarkerError, match=r"results\.md:2: <!-- table: slide-metrics --> has no end marker"):
        check(repo)
    doc.write_text("<!-- table: slide-metrics -->\n<!-- table: slide-speed -->\n")
    with pytest.raises(blocks.MarkerError, match="no end marker .* before the next table starts at line 2"):
        check(repo)
    doc.write_text("<!-- /table: slide-metrics -->\n")
    with pytest.raises(blocks.MarkerError, match=":1: .* ends a table that was not started"):
        check(repo)
    doc.write_text("<!-- table: slide-plots -->\n<!-- /table: slide-plots -->\n")
    with pytest.raises(blocks.MarkerError, match="unknown kind 'plots'; known kinds: metrics"):
        check(repo)
    doc.write_text(EMPTY)
    pd.DataFrame({"method": ["graphdem"], "sim": ["all"]}).to_csv(repo["root"] / "results" / "slide" / "metrics.csv")
    with pytest.raises(ValueError, match=r"metrics\.csv: lacks the columns \['metric'\] that the metrics table"):
        write(repo)


def test_check_through_the_command_line(repo, capsys, monkeypatch):
    monkeypatch.setattr(doc_tables, "KINDS", repo["kinds"])
    monkeypatch.setattr(doc_tables, "CODE_ROOT", repo["code"])
    args = ["tables", "--check", "--root", str(repo["root"])]
    assert cli.main(args) == 0                              # never generated: a warning, not a failure
    out = capsys.readouterr()
    assert out.out == "" and out.err.startswith("warning: ") and "never generated" in out.err
    doc_tables.write(doc_tables.plan(repo["root"], kinds=repo["kinds"], code_root=repo["code"]))
    assert cli.main(args) == 0 and capsys.readouterr().out == ""
    text = repo["doc"].read_text()
    repo["doc"].write_text(re.sub(r"code [0-9a-f]{12}", "code 000000000000", text))
    with pytest.raises(SystemExit) as stop:
        cli.main(args)
    assert stop.value.code == 1 and "stale" in capsys.readouterr().out


def test_the_speed_and_card_tables_of_their_real_csvs(tmp_path):
    from evaluation import card, performance
    contenders = pd.DataFrame([
        {"contender": "dem_reference", "kind": "dem", "stable": True, "seconds_per_rollout": 10.0,
         "seconds_per_frame": 0.5, "seconds_per_dem_step": 1e-4, "mse": 0.0},
        {"contender": "dem_coarse", "kind": "dem", "stable": False, "seconds_per_rollout": NAN,
         "seconds_per_frame": NAN, "seconds_per_dem_step": NAN, "mse": NAN},
        {"contender": "graphdem", "kind": "surrogate", "stable": True, "seconds_per_rollout": 0.25,
         "seconds_per_frame": 0.0125, "seconds_per_dem_step": NAN, "mse": 0.548}])
    bench = performance.report(contenders, "graphdem", "dem_reference", settling_seconds=12.0)
    rows = kinds.speed(bench).splitlines()[2:]
    assert rows == ["| dem_reference | dem | 500 | 0 | 1x |", f"| dem_coarse | dem | {kinds.BLOWN_UP} | "
                    f"{kinds.BLOWN_UP} | {kinds.BLOWN_UP} |", "| graphdem (main) | surrogate | 12.5 | 0.548 | 40x |"]
    measured = {"benchmark": "b", "source": card.MEASURED, "history": 6, "n_predicted": 14, "split": "test",
                "unit": "m^2", "min": 0.5, "max": 0.6, "total": "", "n_seeds": 3, "n_sims": 6, "values": ""}
    table = pd.DataFrame([
        {**measured, "method": "graphdem", "quantity": "rollout_mse", "mean": 0.5481, "std": 0.0512},
        {**measured, "method": "graphdem", "quantity": "blown_up", "unit": "rollouts", "mean": 0.0, "std": 0.0,
         "total": 0.0},
        {**measured, "source": card.ARTICLE, "method": "gns", "quantity": "rollout_mse", "mean": 0.7, "std": ""}],
        columns=list(card.COLUMNS))
    table.to_csv(tmp_path / "card.csv", index=False, na_rep="NaN")
    text = kinds.card(pd.read_csv(tmp_path / "card.csv"))
    assert text.splitlines()[0] == "| quantity | K | Graph-DEM | article: GNS |"
    assert text.splitlines()[2:] == ["| rollout MSE (m^2) | 6 | 0.548 ± 0.051 | 0.7 |",
                                     "| blown up, over all seeds (rollouts) | 6 | 0 |  |"]


def test_the_repositorys_tables_are_current():
    """The check CI runs: no table of the README or docs is stale (never generated ones only warn)."""
    stale, _ = doc_tables.check(doc_tables.CODE_ROOT)
    assert stale == []


def test_the_readmes_summary_gives_each_metrics_error_skill_and_spreads_from_the_csv():
    from evaluation.evaluate import summarise
    from evaluation.metrics.scores import Intervals
    steps = [row for metric in ("rollout MSE", "Max Ht", "Max overlap") for row in
             per_step("graphdem", metric, {"a": 0.1, "b": 0.3})
             + per_step("constant_velocity", metric, {"a": 0.8, "b": 0.8})
             + per_step("dem_ensemble", metric, {"a": 0.2, "b": 0.2})
             + per_step("dem_ensemble", metric, {"a": 0.4, "b": 0.4}, member=1)]
    table = summarise(pd.DataFrame(steps), intervals=Intervals(samples=200, level=0.95, seed=0), units={"Max Ht": "m"})
    text = kinds.summary(table)
    rows = {line.split(" | ")[0].strip("| "): line.strip("|").split(" | ")[1:] for line in text.splitlines()[2:]}
    assert list(rows) == ["rollout MSE (m²)", "Max Ht (m)"]              # a plausibility measure is not summarised
    model = table.query("sim == 'all' and method == 'graphdem'").set_index("metric")
    error, member, skill, spreads, acc, _ = (c.strip() for c in rows["Max Ht (m)"])
    low, mid, high = (model.at["Max Ht", c] for c in ("change_error_ci_low", "change_error", "change_error_ci_high"))
    assert error == f"{mid:{kinds.NUMBER}} [{low:{kinds.NUMBER}}, {high:{kinds.NUMBER}}]"
    assert member.startswith("0.3 ") and skill.startswith(f"{model.at['Max Ht', 'skill']:{kinds.SCORE}} [")
    assert spreads == f"{model.at['Max Ht', 'error_in_spreads']:{kinds.SCORE}}" and acc.endswith("]")
    assert rows["rollout MSE (m²)"][0].startswith(f"{model.at['rollout MSE', 'mse']:{kinds.NUMBER}} [")
    # each metric is named with the CSV's own unit column, not a registry's
    relabelled = kinds.summary(table.assign(unit=table["unit"].replace({"m": "cm"})))
    assert [line.split(" | ")[0].strip("| ") for line in relabelled.splitlines()[2:]] == \
        ["rollout MSE (m²)", "Max Ht (cm)"]
