"""A target no rule makes is refused before the DAG is built, naming the closest targets that exist."""

import subprocess
import sys
from pathlib import Path

import pytest

from graphdem_workflow import targets

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")


def dry_run(workdir, *args):
    cmd = [SNAKEMAKE, "-n", "-s", str(ROOT / "workflow" / "Snakefile"), "-d", str(workdir), *args,
           "--config", "scale=ci"]
    return subprocess.run(cmd, capture_output=True, text=True, cwd=workdir)


def test_a_misspelt_scene_and_file_are_refused_with_the_closest_targets(tmp_path):
    proc = dry_run(tmp_path, "results/slid/metrics.csv", "results/slide/metrcs.csv")
    text = proc.stdout + proc.stderr
    assert proc.returncode != 0 and "MissingRuleException" not in text
    assert "no rule makes 'results/slid/metrics.csv'; did you mean results/slide/metrics.csv" in text
    assert "no rule makes 'results/slide/metrcs.csv'; did you mean results/slide/metrics.csv" in text
    assert "the main targets: results/collapse/metrics.csv, results/meteorite/metrics.csv" in text
    assert not (tmp_path / "results").exists()                 # nothing written


def test_targets_that_rules_make_pass_the_check(tmp_path):
    proc = dry_run(tmp_path, "results/slide/metrics.csv", "results/slide/logs/train.log", "all",
                   "results/meteorite/dataset/stats.json")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "no rule makes" not in proc.stdout + proc.stderr


def test_the_command_line_targets_are_read_by_snakemakes_own_parser():
    class Unset:
        dag_settings = None
    argv = ["/x/bin/snakemake", "-c2", "results/a.csv", "--forcerun", "train", "-n"]
    assert targets.command_line_targets(Unset(), argv) == ["results/a.csv"]
    assert targets.command_line_targets(Unset(), ["python", "results/a.csv"]) == []      # not the snakemake CLI
    module_run = ["/x/lib/snakemake/__main__.py", "results/a.csv"]                        # python -m snakemake
    assert targets.command_line_targets(Unset(), module_run) == ["results/a.csv"]


def test_the_candidates_fill_every_wildcard_with_each_known_value():
    class Rule:
        def __init__(self, *output):
            self.output = output
    rules = [Rule("results/{name}/metrics.csv"), Rule("results/{scene,[a-z]+}/sims/{sim}.h5"),
             Rule("results/{name}/model/best.pt", "results/crosscheck.csv")]
    found = targets.concrete(rules, {"name": ["slide", "shear"], "scene": ["slide"]})
    assert found == ["results/crosscheck.csv", "results/shear/metrics.csv", "results/shear/model/best.pt",
                     "results/slide/metrics.csv", "results/slide/model/best.pt"]      # {sim} unknown: left out
    message = targets.message(["results/slde/metrics.csv"], found, ["slide", "shear"])
    assert message.splitlines()[0] == ("graphdem: no rule makes 'results/slde/metrics.csv'; did you mean "
                                       "results/slide/metrics.csv or results/shear/metrics.csv or "
                                       "results/slide/model/best.pt?")


@pytest.mark.parametrize("word, hint", [("yung", " (did you mean 'young'?)"), ("zzz", "")])
def test_did_you_mean_names_the_closest_choice_or_nothing(word, hint):
    from generators.errors import did_you_mean
    assert did_you_mean(word, ["young", "density", "friction"]) == hint
