"""The config's device and launch keys in the workflow: the commands and GPU requests they make, and that
changing them reruns no job (they say where the arithmetic runs, not what it computes)."""

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from generators import config
from graphdem_workflow import launch

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")


def test_launch_settings_make_the_train_command_and_the_gpu_requests():
    cfg = config.load({"scale": "ci"})
    assert (cfg["device"], cfg["launch"]) == ("auto", {"launcher": "plain", "processes": 1})     # the defaults
    assert launch.train_command(cfg) == ["graphdem"] and launch.train_gpus(cfg) == launch.gpus(cfg) == 0
    cfg = config.load({"scale": "ci", "device": "cuda", "launch": {"launcher": "torchrun", "processes": 4}})
    assert launch.train_command(cfg) == ["torchrun", "--standalone", "--nproc-per-node", "4", "-m", "graphdem"]
    assert launch.train_gpus(cfg) == 4 and launch.gpus(cfg) == 1
    assert launch.device_args(cfg) == ["--device", "cuda"]
    cpu = config.load({"device": "cpu", "launch": {"launcher": "torchrun", "processes": 2}})
    assert launch.train_gpus(cpu) == 0          # gloo processes on the CPU ask for no GPU
    assert repr(launch.device_args(cfg)) == repr(launch.device_args(cpu)) == repr(launch.train_command(cpu))
    with pytest.raises(config.ConfigError, match="'launch.processes' = 2 needs 'launch.launcher' = 'torchrun'"):
        config.load({"launch": {"launcher": "plain", "processes": 2}})
    with pytest.raises(config.ConfigError, match="'launch.launcher' = 'srun' is not allowed"):
        config.load({"launch": {"launcher": "srun", "processes": 2}})


SNAKEFILE = """
from graphdem_workflow.launch import MachineArgs
rule job:
    output: "out.txt"
    params:
        device=lambda wildcards: MachineArgs(["--device", config["device"]]),
        other=lambda wildcards: ["--other", str(config["other"])],
    shell: "echo {params.device:q} {params.other:q} > {output:q}"
"""


def _snakemake(workdir: Path, *args: str) -> str:
    path = os.pathsep.join([str(ROOT / "workflow"), os.environ.get("PYTHONPATH", "")])  # this tree's helpers
    proc = subprocess.run([SNAKEMAKE, "-c1", "-s", str(workdir / "Snakefile"), "-d", str(workdir), *args],
                          capture_output=True, text=True, cwd=workdir, env={**os.environ, "PYTHONPATH": path})
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc.stdout + proc.stderr


def test_a_machine_setting_reruns_no_job_while_another_param_does(tmp_path):
    (tmp_path / "Snakefile").write_text(SNAKEFILE)
    _snakemake(tmp_path, "--config", "device=cpu", "other=1")
    assert (tmp_path / "out.txt").read_text().split() == ["--device", "cpu", "--other", "1"]   # passed as words
    assert "Nothing to be done" in _snakemake(tmp_path, "-n", "--config", "device=cuda:1", "other=1")
    assert "Nothing to be done" not in _snakemake(tmp_path, "-n", "--config", "device=cpu", "other=2")


def _dry_run(tmp_path: Path, *config: str) -> dict[str, tuple[list[str], str]]:
    """Per rule of a dry run to the slide's metrics: the first job's shell words and its resources line."""
    proc = subprocess.run([SNAKEMAKE, "-n", "-p", "-s", str(ROOT / "workflow" / "Snakefile"), "-d", str(tmp_path),
                           "results/slide/metrics.csv", "--config", "scale=ci", *config],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    jobs = {}
    for block in re.split(r"^rule ", proc.stdout + proc.stderr, flags=re.M)[1:]:
        name = block.split(":", 1)[0]
        command = next(line for line in block.splitlines() if line.startswith("Shell command: "))
        command = command.removeprefix("Shell command: ")
        resources = next(line for line in block.splitlines() if line.strip().startswith("resources:"))
        jobs.setdefault(name, (shlex.split(command.split(">")[0]), resources))
    return jobs


def test_the_jobs_take_the_device_and_the_train_job_its_launcher(tmp_path):
    jobs = _dry_run(tmp_path / "plain")
    words, resources = jobs["train"]
    assert words[:2] == ["graphdem", "train"] and words[words.index("--device") + 1] == "auto"
    assert "gpus=0" in resources
    jobs = _dry_run(tmp_path / "gpus", "device=cuda", "launch={launcher: torchrun, processes: 2}")
    words, resources = jobs["train"]
    assert words[:7] == ["torchrun", "--standalone", "--nproc-per-node", "2", "-m", "graphdem", "train"]
    assert words[words.index("--device") + 1] == "cuda" and "gpus=2" in resources
    for rule in ("rollout", "evaluate"):
        words, resources = jobs[rule]
        assert words[words.index("--device") + 1] == "cuda" and "gpus=1" in resources, rule
