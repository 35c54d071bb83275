"""Every command the README and the Snakefile header document works as written, and does what its text says.

Each `snakemake` command line is dry-run at ci scale, in an empty folder (what the target builds) and, where
the text promises to rerun only part of a finished run, in the finished ci run of the workflow tests; the
jobs are checked against a promise written here per command. A documented command without a promise fails
the test. The `graphdem` command lines run for real on the ci results, and the README's Python blocks run as
doctests there.
"""

from __future__ import annotations

import doctest
import re
import shlex
import shutil
import subprocess
import sys
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
SNAKEFILE = ROOT / "workflow" / "Snakefile"

pytestmark = pytest.mark.engine


def documented_lines() -> list[str]:
    """Command lines of the README's code blocks and of the Snakefile's header comment, comments removed."""
    lines = []
    for block in re.findall(r"```[a-z]*\n(.*?)```", (ROOT / "README.md").read_text(), re.S):
        lines += [line for line in block.splitlines() if line.startswith(("snakemake ", "graphdem "))]
    for line in SNAKEFILE.read_text().splitlines():
        if not line.startswith("#"):
            break
        if line.lstrip("# ").startswith("snakemake "):
            lines.append(line.lstrip("# "))
    return [shlex.join(shlex.split(line, comments=True)) for line in lines]


def snakemake_args(line: str) -> list[str]:
    """The arguments after `snakemake`, without the core count (a dry run needs none)."""
    return [a for a in shlex.split(line)[1:] if not re.fullmatch(r"-c\d*|--cores=?\d*", a)]


# What each documented `snakemake` command promises, keyed by its arguments (cores left out):
#   "builds": the folders under results/ a dry run from nothing writes into, and a rule that must be among its jobs;
#   "reruns": the exact rules a dry run plans in the finished ci run (only for commands that promise a partial rerun).
SLIDE = {"builds": ({"slide"}, "evaluate")}
PROMISES = {
    "results/slide/metrics.csv": SLIDE,
    "results/slide/metrics.csv --config scale=ci": SLIDE,
    "-d runs/ci results/slide/metrics.csv --config scale=ci": SLIDE,
    "results/meteorite/metrics.csv": {"builds": ({"meteorite"}, "evaluate")},
    "results/shear/metrics.csv": {"builds": ({"shear"}, "evaluate")},
    "results/collapse/metrics.csv": {"builds": ({"collapse"}, "evaluate")},
    "results/meteorite/metrics.csv --config 'meteorite={ranks: 2}'":      # how LAMMPS runs: reruns nothing
        {"builds": ({"meteorite"}, "evaluate"), "reruns": set()},
    "results/collapse/physics.csv": {"builds": ({"collapse"}, "physics")},
    "-d runs/paper results/collapse/physics.csv --config scale=paper": {"builds": ({"collapse"}, "physics")},
    "results/slide/dataset/stats.json": {"builds": ({"slide"}, "dataset"), "never": {"train", "evaluate"}},
    "results/slide/metrics.csv --forcerun train": {**SLIDE, "reruns": {"train", "rollout", "evaluate"}},
    "results/slide/metrics.csv --config 'slide={train: {noise_std: 0.01}}'":
        {**SLIDE, "reruns": {"train", "rollout", "evaluate"}},
    "results/slide/metrics.csv --config 'slide={young: 5.0e9}'":
        {**SLIDE, "reruns": {"sweep", "prepare", "simulate", "convert", "dataset", "train", "rollout", "evaluate"}},
    "results/slide/metrics.csv --config 'slide={weak_friction: 0.1, n_sims: 100}'":
        {**SLIDE, "reruns": {"sweep", "simulate", "convert", "dataset", "train", "rollout", "evaluate"}},
    "results/slide/metrics.csv --config 'slide={sweep: {weak_dip: [5.0, 15.0]}}'":
        {**SLIDE, "reruns": {"sweep", "simulate", "convert", "dataset", "train", "rollout", "evaluate"}},
    "results/meteorite/metrics.csv --config 'meteorite={sweep: {speed: [80.0, 200.0], n_speeds: 8}}'":
        {"builds": ({"meteorite"}, "evaluate"),
         "reruns": {"sweep", "simulate", "convert", "dataset", "train", "rollout", "evaluate"}},
    "results/shear/metrics.csv --config 'shear={friction: 0.4, sweep: {young: [5.0e6, 5.0e7]}}'":
        {"builds": ({"shear"}, "evaluate"),
         "reruns": {"sweep", "prepare", "simulate", "convert", "dataset", "train", "rollout", "evaluate"}},
    "results/shear/metrics.csv --config scale=ci 'shear={engine: lammps}'":
        {"builds": ({"shear"}, "evaluate"),
         "reruns": {"sweep", "prepare", "simulate", "convert", "dataset", "train", "rollout", "evaluate"}},
    "results/slide/vtk": {"builds": ({"slide"}, "export")},
    "results/slide/metrics.csv --resources gpus=1 --config device=cuda": SLIDE,
    "--workflow-profile workflow/profiles/slurm results/slide/metrics.csv --config scale=paper":
        {"tested_by": "tests/workflow/test_slurm.py"},
    "results/slide/seeds.csv --config seeds=3": {"builds": ({"slide"}, "train_seed")},
    "results/slide/performance.csv results/slide/stability.csv": {"builds": ({"slide"}, "performance")},
    "results/shear/performance.csv": {"builds": ({"shear"}, "performance")},
    "results/shear/stability.csv": {"builds": ({"shear"}, "stability")},
    "results/shear/property_sensitivity.csv": {"builds": ({"shear"}, "property_sensitivity")},
    "results/shear/shear_stress.csv": {"builds": ({"shear"}, "shear_stress_check")},
    "results/crosscheck.csv": {"builds": ({"slide", "meteorite", "shear", "collapse", "crosscheck"}, "crosscheck_all")},
    "results/crosscheck.csv --config scale=ci":
        {"builds": ({"slide", "meteorite", "shear", "collapse", "crosscheck"}, "crosscheck_all")},
    "results/crosscheck/slide_transfer.csv": {"builds": ({"slide", "crosscheck"}, "transfer")},
    "results/slide_samer/metrics.csv --config solidgn_root=/path/to/solidgn":
        {"builds": ({"slide_samer"}, "import_solidgn")},
    "results/slide_samer/card.md --config solidgn_root=/path/to/solidgn": {"builds": ({"slide_samer"}, "card")},
    "benchmarks --config solidgn_root=/path/to/solidgn": {"builds": ({"slide_samer", "slide_small"}, "card")},
    "results/mine/metrics.csv --config user_data=/path/to/mine": {"builds": ({"mine"}, "dataset_user")},
}


def fake_solidgn(root: Path) -> Path:
    """A folder shaped like Solid-GN's data/ (what a dry run reads: each set's metadata.json)."""
    for source in ("Slide_Same_R", "Slide"):
        (root / source / "train").mkdir(parents=True)
        (root / source / "valid").mkdir()
        (root / source / "metadata.json").write_text('{"bounds": [[0, 100], [0, 80]], "dim": 2, "dt": 0.001}')
    return root


def fake_user_data(root: Path) -> Path:
    """A folder of a user's sims named mine/ (a dry run reads only their names)."""
    (root / "mine").mkdir(parents=True)
    for i in range(10):
        (root / "mine" / f"mine_{i:04d}.h5").write_bytes(b"")
    return root / "mine"


def dry_run(args: list[str], workdir: Path, solidgn: Path) -> list[tuple[str, set[str]]]:
    """The planned jobs of a documented command: (rule, the results/ folders its outputs lie in), per job."""
    args = [a.replace("/path/to/solidgn", str(solidgn)) for a in args]
    if any("/path/to/mine" in a for a in args):
        mine = fake_user_data(workdir.parent / f"{workdir.name}_user")
        args = [a.replace("/path/to/mine", str(mine)) for a in args]
    if "-d" in args:                                   # its own working directory, placed inside ours
        i = args.index("-d")
        workdir = workdir / args[i + 1]
        del args[i:i + 2]
    if "--config" in args:
        i = args.index("--config") + 1
        while i < len(args) and not args[i].startswith("-"):
            i += 1
        if not any(a.startswith("scale=") for a in args):
            args.insert(i, "scale=ci")
    else:
        args += ["--config", "scale=ci"]
    cmd = [str(BIN / "snakemake"), "-n", *args, "-s", str(SNAKEFILE), "-d", str(workdir)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, f"{shlex.join(cmd)}\n{proc.stdout[-2000:]}{proc.stderr[-2000:]}"
    jobs, rule = [], None
    for line in proc.stdout.splitlines():
        if m := re.match(r"(?:local)?rule (\w+):$", line):
            rule = m[1]
        elif rule and line.startswith("    output: "):
            outputs = line.split(": ", 1)[1].split(", ")
            jobs.append((rule, {Path(o).parts[1].removesuffix(".csv") for o in outputs if o.startswith("results/")}))
            rule = None
        elif rule and not line.startswith("    "):
            jobs.append((rule, set()))
            rule = None
    return jobs


def test_every_documented_snakemake_command_has_a_promise():
    commands = {shlex.join(snakemake_args(line)) for line in documented_lines() if line.startswith("snakemake ")}
    assert commands - PROMISES.keys() == set(), "documented commands with no promise in PROMISES"
    assert PROMISES.keys() - commands == set(), "promises of commands no longer documented"
    assert "results/slide/metrics.csv --forcerun train" in commands      # target before --forcerun, which
    assert not any(c.startswith(("--forcerun", "--resources")) for c in commands)   # would swallow it
    for key, promise in PROMISES.items():                                  # tested elsewhere: that test runs it
        if "tested_by" in promise:
            assert all(arg in (ROOT / promise["tested_by"]).read_text() for arg in ("scale=paper", "slurm")), key


def test_each_documented_command_builds_what_its_text_says(tmp_path):
    solidgn = fake_solidgn(tmp_path / "solidgn")

    def check(key: str) -> str | None:
        if "tested_by" in PROMISES[key]:               # a dry run of its own, with what it needs (fake SLURM)
            return None
        workdir = tmp_path / re.sub(r"\W+", "_", key)[:80]
        workdir.mkdir()
        jobs = dry_run(shlex.split(key), workdir, solidgn)
        folders, rule = PROMISES[key]["builds"]
        written = set().union(*(f for _, f in jobs)) if jobs else set()
        rules = {r for r, _ in jobs}
        if written != folders or rule not in rules or rules & PROMISES[key].get("never", set()):
            return f"{key}: writes into {sorted(written)} with rules {sorted(rules)}"
        return None

    with ThreadPoolExecutor(2) as pool:
        failures = [f for f in pool.map(check, PROMISES) if f]
    assert failures == []


def test_documented_partial_reruns_rerun_only_what_they_say(ci_results, tmp_path):
    solidgn = fake_solidgn(tmp_path / "solidgn")
    reruns = {key: p["reruns"] for key, p in PROMISES.items() if "reruns" in p}

    def check(key: str) -> str | None:
        jobs = dry_run(shlex.split(key), ci_results.parent, solidgn)
        rules, folders = Counter(r for r, _ in jobs), set().union(*(f for _, f in jobs))
        scene = next(iter(PROMISES[key]["builds"][0]))
        if set(rules) != reruns[key] or not folders <= {scene}:
            return f"{key}: reruns {dict(rules)} in {sorted(folders)}"
        return None

    with ThreadPoolExecutor(2) as pool:
        failures = [f for f in pool.map(check, reruns) if f]
    assert failures == []


@pytest.fixture
def user_folder(ci_results, tmp_path):
    """A folder of a user's own: the ci results beside a copy of one test sim in my_sims/."""
    (tmp_path / "results").symlink_to(ci_results)
    (tmp_path / "my_sims").mkdir()
    test_sim = sorted((ci_results / "slide" / "rollouts").glob("*.h5"))[0].name
    shutil.copy(ci_results / "slide" / "sims" / test_sim, tmp_path / "my_sims" / test_sim)
    return tmp_path


def test_documented_graphdem_commands_run_as_written(user_folder):
    lines = [line for line in documented_lines() if line.startswith("graphdem")]
    assert len(lines) >= 4
    for line in lines:
        args = shlex.split(line)
        proc = subprocess.run([str(BIN / args[0]), *args[1:]], cwd=user_folder, capture_output=True, text=True)
        assert proc.returncode == 0, f"{line}\n{proc.stdout[-1500:]}{proc.stderr[-1500:]}"
    assert (user_folder / "my.csv").is_file()


def test_the_readme_python_blocks_run_as_doctests(user_folder, monkeypatch):
    monkeypatch.chdir(user_folder)
    text = "\n".join(re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S))
    assert text.count(">>>") >= 7
    test = doctest.DocTestParser().get_doctest(text, {}, "README.md", "README.md", 0)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    runner.run(test)
    assert runner.summarize(verbose=False).failed == 0
