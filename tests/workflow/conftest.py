"""One ci-scale run of the slide, meteorite and shear scenes (the default ci config, with the shear's
property-sensitivity test and shear-stress check) and of the cross-check
of all four scenes in LAMMPS and YADE (with the slide's and the shear's transfer scores), shared by the
workflow tests; two engine jobs run side by side under -c2. Under pytest-xdist the run is made once, by the
first worker that needs it, and read by the other (a file lock in the workers' shared temporary folder)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from filelock import FileLock

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")


def _run_ci_scenes(wd: Path) -> dict:
    targets = [f"results/{scene}/metrics.csv" for scene in ("meteorite", "shear", "slide")]
    targets += ["results/shear/property_sensitivity.csv", "results/shear/shear_stress.csv", "results/crosscheck.csv",
                *(f"results/crosscheck/{scene}_transfer.csv" for scene in ("slide", "shear"))]
    snakefile = str(ROOT / "workflow" / "Snakefile")
    proc = subprocess.run([SNAKEMAKE, "-c2", "-s", snakefile, "-d", str(wd), "--config", "scale=ci",
                           "--", *targets], capture_output=True, text=True)
    return {"returncode": proc.returncode, "tail": proc.stdout[-3000:] + proc.stderr[-3000:]}


@pytest.fixture(scope="session")
def ci_results(tmp_path_factory) -> Path:
    if "PYTEST_XDIST_WORKER" not in os.environ:            # one process: its own temporary folder
        wd = tmp_path_factory.mktemp("ci_scenes")
        outcome = _run_ci_scenes(wd)
    else:                                                  # the workers share the parent of their base temp
        shared = tmp_path_factory.getbasetemp().parent
        wd, done = shared / "ci_scenes", shared / "ci_scenes.json"
        with FileLock(str(shared / "ci_scenes.lock")):
            if not done.is_file():
                wd.mkdir(exist_ok=True)
                done.write_text(json.dumps(_run_ci_scenes(wd)))
            outcome = json.loads(done.read_text())
    assert outcome["returncode"] == 0, outcome["tail"]
    return wd / "results"
