"""One ci-scale run of the slide, meteorite and shear scenes (the default ci config, with the shear's property
test and stress test) and of the cross-check
of all four scenes in LAMMPS and YADE (with the slide's and the shear's transfer scores), shared by the
workflow tests; two engine jobs run side by side under -c2."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")


@pytest.fixture(scope="session")
def ci_results(tmp_path_factory) -> Path:
    wd = tmp_path_factory.mktemp("ci_scenes")
    targets = [f"results/{scene}/metrics.csv" for scene in ("meteorite", "shear", "slide")]
    targets += ["results/shear/property.csv", "results/shear/stress.csv", "results/crosscheck.csv",
                *(f"results/crosscheck/{scene}_transfer.csv" for scene in ("slide", "shear"))]
    snakefile = str(ROOT / "workflow" / "Snakefile")
    proc = subprocess.run([SNAKEMAKE, "-c2", "-s", snakefile, "-d", str(wd), "--config", "scale=ci",
                           "--", *targets], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return wd / "results"
