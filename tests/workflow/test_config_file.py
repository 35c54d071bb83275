"""config/config.yaml: the user's overrides read by the Snakefile's configfile, its examples valid keys, the
workflow usable as a Snakemake module."""

import re
import subprocess
import sys
from pathlib import Path

import yaml

from generators import config

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")
SHIPPED = ROOT / "config" / "config.yaml"


def planned_sims(proc) -> int:
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return int(re.search(r"^simulate\s+(\d+)\s*$", proc.stdout + proc.stderr, re.M)[1])


def test_the_shipped_file_changes_nothing_and_its_examples_are_valid_keys():
    assert yaml.safe_load(SHIPPED.read_text()) == {}
    lines = SHIPPED.read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("# Examples")) + 1
    examples = "\n".join(line[2:] for line in lines[start:] if line.startswith("# "))
    overrides = yaml.safe_load(examples)
    assert {"scale", "device", "seeds", "solidgn_root", "slide", "meteorite"} <= set(overrides)
    resolved = config.load(overrides)                      # validated: a misspelt example would be refused
    assert resolved["slide"]["young"] == 5.0e9 and resolved["slide"]["train"]["epochs"] == 30
    assert resolved["scale"] == "ci" and resolved["meteorite"]["ranks"] == 2


def test_the_working_directorys_config_file_is_read_and_the_command_line_wins(tmp_path):
    (tmp_path / "config").mkdir()
    (tmp_path / "config" / "config.yaml").write_text("scale: ci\nslide: {n_sims: 9}\n")
    base = [SNAKEMAKE, "-n", "-s", str(ROOT / "workflow" / "Snakefile"), "-d", str(tmp_path),
            "results/slide/metrics.csv"]
    members = config.load({"scale": "ci"})["slide"]["evaluate"]["ensemble_members"]
    test_sims = 1                                               # ci: 9 sims split 0.7/0.2/0.1
    assert planned_sims(subprocess.run(base, capture_output=True, text=True)) == 9 + members * test_sims
    proc = subprocess.run([*base, "--config", "slide={n_sims: 4}"], capture_output=True, text=True)
    assert planned_sims(proc) == 4 + members * test_sims


def test_the_workflow_runs_as_a_module_of_another_workflow(tmp_path):
    (tmp_path / "config").mkdir()
    (tmp_path / "config" / "config.yaml").write_text("scale: ci\n")
    (tmp_path / "Snakefile").write_text(
        'configfile: "config/config.yaml"\n\n'
        f'module graphdem:\n    snakefile: "{ROOT / "workflow" / "Snakefile"}"\n    config: config\n\n'
        "use rule * from graphdem as graphdem_*\n\n"
        'rule summary:\n    input: "results/slide/metrics.csv"\n    output: "summary.txt"\n'
        '    shell: "head -1 {input} > {output}"\n')
    proc = subprocess.run([SNAKEMAKE, "-n", "summary.txt"], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]     # the project's own rule's target
    assert re.search(r"^graphdem_evaluate\s+1\s*$", proc.stdout, re.M)
    assert re.search(r"^summary\s+1\s*$", proc.stdout, re.M)
