"""The guard of snakemake --report (workflow/graphdem_workflow/report.py): refused while a job of the report's DAG
has an output that was never built, with the count per rule; passed (once per DAG) when every output exists."""

from types import SimpleNamespace

import pytest

from graphdem_workflow import report


def dag(tmp_path, outputs: dict[str, list[str]]):
    jobs = [SimpleNamespace(rule=SimpleNamespace(name=rule), output=[str(tmp_path / f) for f in files])
            for rule, files in outputs.items()]
    return SimpleNamespace(jobs=jobs)


def test_a_dag_with_unbuilt_outputs_is_refused_with_counts_per_rule(tmp_path):
    (tmp_path / "metrics.csv").write_text("x")
    graph = dag(tmp_path, {"evaluate": ["metrics.csv"], "simulate": ["raw/a", "raw/b"], "convert": ["sims/a.h5"]})
    assert report.unbuilt(graph) == [("simulate", str(tmp_path / "raw/a")), ("simulate", str(tmp_path / "raw/b")),
                                     ("convert", str(tmp_path / "sims/a.h5"))]
    with pytest.raises(report.ReportError) as err:
        report.check(graph)
    text = str(err.value)
    assert "3 outputs" in text and "(simulate 2, convert 1;" in text and "--config scale=ci" in text
    with pytest.raises(report.ReportError):                 # refused again: a refusal is not remembered
        report.check(graph)


def test_a_built_dag_passes(tmp_path):
    (tmp_path / "raw").mkdir()
    (tmp_path / "metrics.csv").write_text("x")
    graph = dag(tmp_path, {"evaluate": ["metrics.csv"], "simulate": ["raw"], "all": []})
    report.check(graph)
    report.check(graph)
    report.check(None)                                      # no DAG (not building a report): nothing to check
