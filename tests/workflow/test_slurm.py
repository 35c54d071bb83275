"""The SLURM profile (workflow/profiles/slurm): a paper-scale dry run through the SLURM executor plugin, without
a cluster. SLURM's commands are faked on PATH: each call is recorded and fails, so the test proves that the dry
run submits nothing. From the run's output: each sim's simulate and convert jobs are grouped, 50 sims per
submission, and every job carries the resources the profile gives its rule; Snakemake's own group sizing then
gives the request of one group submission that the profile's comments state."""

import math
import os
import re
import subprocess
import sys
from collections import Counter
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml
from snakemake.resources import GroupResources, Resources

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")
PROFILE_DIR = ROOT / "workflow" / "profiles" / "slurm"
PROFILE = yaml.safe_load((PROFILE_DIR / "config.yaml").read_text())
SLURM_COMMANDS = ("sbatch", "srun", "scancel", "sinfo", "squeue", "sacct", "scontrol", "sacctmgr", "sshare")
SUBMITTING = {"sbatch", "srun", "scancel"}
PAPER_SIMS = 1000
PAPER_TEST_SIMS = 100          # the test split, each replayed and perturbed by every DEM ensemble member
PAPER_MEMBERS = 5              # slide.evaluate.ensemble_members at the paper scale


def parse_resources(text: str) -> dict:
    """A dry run's `resources:` line as a dict, integers as int (`<TBD>` values are left as text)."""
    items = (item.split("=", 1) for item in text.split(", "))
    return {k: int(v) if v.isdigit() else v for k, v in items}


def parse_dry_run(text: str) -> list[dict]:
    """Every planned job: rule, wildcards, threads, resources, and the group job it belongs to: (group name, its
    number in the output), None for a job outside any group. A group job lists its jobs indented under its header."""
    jobs, group, job, n_groups = [], None, None, 0
    for line in text.splitlines():
        if m := re.search(r"\] Group job (\S+) \(jobs in lexicogr\. order\):$", line):
            n_groups += 1
            group = (m[1], n_groups)
            continue
        if m := re.match(r"( *)(?:local)?rule (\w+):$", line):
            if not m[1]:
                group = None                       # an unindented job ends the group listed before it
            job = {"rule": m[2], "group": group, "wildcards": {}, "resources": {}, "threads": 1}
            jobs.append(job)
        elif job and (m := re.match(r" +threads: (\d+)$", line)):       # printed only when more than 1
            job["threads"] = int(m[1])
        elif job and (m := re.match(r" +wildcards: (.*)$", line)):
            job["wildcards"] = dict(item.split("=", 1) for item in m[1].split(", "))
        elif job and (m := re.match(r" +resources: (.*)$", line)):
            job["resources"] = parse_resources(m[1])
    return jobs


@pytest.fixture(scope="module")
def dry_run(tmp_path_factory) -> SimpleNamespace:
    tmp = tmp_path_factory.mktemp("slurm")
    fake_bin, calls = tmp / "bin", tmp / "calls.log"
    fake_bin.mkdir()
    for name in SLURM_COMMANDS:
        fake = fake_bin / name
        fake.write_text(f'#!/bin/sh\necho "{name} $*" >> "{calls}"\necho "{name}: no SLURM cluster here" >&2\nexit 1\n')
        fake.chmod(0o755)
    env = {**os.environ, "PATH": f"{fake_bin}:{Path(sys.executable).parent}:/usr/bin:/bin"}
    cmd = [SNAKEMAKE, "-n", "--workflow-profile", str(PROFILE_DIR), "-s", str(ROOT / "workflow" / "Snakefile"),
           "-d", str(tmp / "wd"), "results/slide/metrics.csv", "--config", "scale=paper"]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    called = calls.read_text().splitlines() if calls.exists() else []
    return SimpleNamespace(text=proc.stdout + proc.stderr, jobs=parse_dry_run(proc.stdout), calls=called)


def test_the_dry_run_uses_the_slurm_executor_and_submits_nothing(dry_run):
    assert "Using workflow specific profile" in dry_run.text and str(PROFILE_DIR) in dry_run.text
    assert PROFILE["executor"] == "slurm"
    # the plugin may query the cluster's configuration while reading its settings; it never submits in a dry run
    assert not [c for c in dry_run.calls if c.split()[0] in SUBMITTING], dry_run.calls
    counts = Counter(j["rule"] for j in dry_run.jobs)
    assert counts["simulate"] == counts["convert"] == PAPER_SIMS + PAPER_MEMBERS * PAPER_TEST_SIMS
    runs = Counter(j["wildcards"]["run"] for j in dry_run.jobs if j["rule"] == "simulate")
    assert runs == {"slide": PAPER_SIMS, **{f"slide/ensemble/m{j}": PAPER_TEST_SIMS for j in range(PAPER_MEMBERS)}}
    assert counts["train"] == counts["evaluate"] == 1 and counts["rollout"] == 100


def test_each_sims_simulate_and_convert_are_grouped_fifty_to_a_submission(dry_run):
    per_sim = PROFILE["group-components"]["sims"]
    assert PROFILE["groups"] == {"simulate": "sims", "convert": "sims"} and per_sim == 50
    groups: dict = {}
    for job in dry_run.jobs:
        if job["group"] is not None:
            groups.setdefault(job["group"], []).append(job)
    assert all(j["group"] is not None for j in dry_run.jobs if j["rule"] in ("simulate", "convert"))
    assert {name for name, _ in groups} == {"sims"}
    # 30 submissions, not 3000: the 1000 sims and the ensemble's 5 x 100 members
    assert len(groups) == math.ceil((PAPER_SIMS + PAPER_MEMBERS * PAPER_TEST_SIMS) / per_sim) == 30
    for members in groups.values():
        sims = {rule: sorted((j["wildcards"]["run"], j["wildcards"]["sim"]) for j in members if j["rule"] == rule)
                for rule in ("simulate", "convert")}
        assert len(members) == 2 * per_sim and sims["simulate"] == sims["convert"]    # whole sims, both steps
        assert {j["rule"] for j in members} == {"simulate", "convert"}
    # what reaches SLURM for results/slide/metrics.csv: 3114 jobs in 144 submissions
    ungrouped = Counter(j["rule"] for j in dry_run.jobs if j["group"] is None)
    assert ungrouped == {"sweep": 1, "prepare": 10, "dataset": 1, "train": 1, "rollout": 100, "evaluate": 1}
    assert len(dry_run.jobs) == 3114 and len(groups) + ungrouped.total() == 144


def test_every_job_gets_the_resources_the_profile_gives_its_rule(dry_run):
    default, per_rule = PROFILE["default-resources"], PROFILE["set-resources"]
    seen = set()
    for job in dry_run.jobs:
        expected = {**default, **per_rule.get(job["rule"], {})}
        got = {k: job["resources"].get(k) for k in expected}
        assert got == expected, f"{job['rule']} {job['wildcards']}: {got} != {expected}"
        assert ("gpu" in job["resources"]) == (job["rule"] in ("train", "rollout", "evaluate")), job
        assert job["threads"] == job["resources"]["cpus_per_task"], job      # SLURM gives what the job uses
        seen.add(job["rule"])
    assert set(per_rule) <= seen                  # the dry run covered every rule the profile sizes


def test_one_group_submission_asks_for_what_the_profile_says(dry_run):
    """Snakemake sizes a group submission from its jobs (GroupResources.basic_layered: parallel jobs summed up
    to --cores, layers in series, runtime added); the profile's comment states 10 CPUs, 10 x 1000 MB, 35 min."""
    group = next(j["group"] for j in dry_run.jobs if j["group"] is not None)
    members = [j for j in dry_run.jobs if j["group"] == group]
    toposorted = [[SimpleNamespace(pipe_group=None, resources={
        "_cores": j["threads"], "_nodes": 1, **{k: v for k, v in j["resources"].items() if isinstance(v, int)}})
        for j in members if j["rule"] == rule] for rule in ("simulate", "convert")]
    assert [len(level) for level in toposorted] == [50, 50]
    request = GroupResources.basic_layered(toposorted, Resources.from_mapping({"_cores": PROFILE["cores"]}),
                                           run_local=False)
    assert request["_cores"] == request["cpus_per_task"] == PROFILE["cores"] == 10
    assert request["mem_mb"] == 10 * 1000
    assert request["runtime"] == 5 * 5 + 5 * 2 == 35
