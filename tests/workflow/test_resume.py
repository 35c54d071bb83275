"""Resume after kill -9: the same command, rerun after the whole Snakemake process group is killed during a
simulate job and again during training, finishes with bit-identical sims and weights, and leaves no temporary."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import torch

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")
TARGET = "results/slide/model/best.pt"
CONFIG = ["scale=ci", "slide={n_sims: 3, frames: 8, record_start: 0.5, settle_time: 4.0, "
          "train: {epochs: 4, patience: 4, checkpoint_every: 1}}"]

pytestmark = pytest.mark.engine


def command(workdir: Path) -> list[str]:
    # -c1: one torch thread, so the reference and the resumed training are bitwise comparable
    return [SNAKEMAKE, "-c1", "-s", str(ROOT / "workflow" / "Snakefile"), "-d", str(workdir), TARGET,
            "--config", *CONFIG]


def kill_when(workdir: Path, ready) -> None:
    """Start the command in its own process group and SIGKILL the whole group once ``ready()`` holds."""
    proc = subprocess.Popen(command(workdir), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    deadline = time.monotonic() + 300
    while not ready():
        assert proc.poll() is None, "the run ended before the kill point"
        assert time.monotonic() < deadline, "kill point not reached"
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


def positions(path: Path) -> np.ndarray:
    with h5py.File(path, "r") as f:
        return f["particles/all/position/value"][()]


def test_the_same_command_resumes_after_kill_9_with_identical_results(tmp_path):
    reference, killed = tmp_path / "reference", tmp_path / "killed"
    # the uninterrupted reference runs beside the killed runs (each is one core, -c1)
    with (tmp_path / "reference.log").open("w") as reference_log:        # the child keeps its own descriptor
        uninterrupted = subprocess.Popen(command(reference), stdout=reference_log, stderr=subprocess.STDOUT)
    raw = killed / "results" / "slide" / "raw"
    kill_when(killed, lambda: raw.is_dir() and any(p.name.startswith(".slide_") for p in raw.iterdir()))
    assert (killed / ".snakemake" / "locks").is_dir() and any((killed / ".snakemake" / "locks").iterdir())
    last = killed / "results" / "slide" / "model" / "last.pt"
    kill_when(killed, last.is_file)                    # the same command again, killed mid-training

    proc = subprocess.run(command(killed), capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "removed the locks of a killed Snakemake run" in proc.stderr
    train_log = (killed / "results" / "slide" / "logs" / "train.log").read_text()
    assert "resuming from results/slide/model/last.pt" in train_log

    assert uninterrupted.wait() == 0, (tmp_path / "reference.log").read_text()[-3000:]
    res_ref, res = reference / "results" / "slide", killed / "results" / "slide"
    for sim in sorted((res_ref / "sims").glob("*.h5")):
        assert np.array_equal(positions(sim), positions(res / "sims" / sim.name)), sim.name
    a = torch.load(res_ref / "model" / "best.pt", weights_only=True)["model"]
    b = torch.load(res / "model" / "best.pt", weights_only=True)["model"]
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    assert not [p for p in res.rglob("*") if ".tmp-" in p.name]
