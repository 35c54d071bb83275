"""User data in the workflow (docs/user-data.md): a folder of real H5MD sims (the tiny ci-scale slide sims of the
shared ``tiny_dataset`` fixture, copied under names no scene's sims have) run through dataset, train, rollout and
evaluate at ci scale with the generic metrics only; a name, folder or scale the workflow cannot take is refused
before anything runs."""

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from generators import config, h5md, sweep

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")
TARGET = "results/mine/metrics.csv"
GENERIC = {"rollout MSE", "Max overlap", "P99 overlap", "Outside box", "Through wall", "Kinetic energy",
           "seconds per frame"}

pytestmark = pytest.mark.engine


def snakemake(workdir: Path, *args: str, config_args: tuple[str, ...] = ()):
    cmd = [SNAKEMAKE, *args, "-s", str(ROOT / "workflow" / "Snakefile"), "-d", str(workdir), "--config", "scale=ci",
           *config_args]
    return subprocess.run(cmd, capture_output=True, text=True)


@pytest.fixture(scope="module")
def folder(tiny_dataset, tmp_path_factory) -> Path:
    """The tiny dataset's 4 real slide sims (10 frames), named Run-0.h5 .. Run-3.h5."""
    out = tmp_path_factory.mktemp("user") / "mine"
    out.mkdir()
    for i, path in enumerate(sorted((tiny_dataset["root"] / "sims").glob("*.h5"))):
        shutil.copyfile(path, out / f"Run-{i}.h5")
    return out


@pytest.fixture(scope="module")
def workdir(folder, tmp_path_factory) -> Path:
    wd = tmp_path_factory.mktemp("user_wf")
    proc = snakemake(wd, TARGET, "-c2", config_args=(f"user_data={folder}",))
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return wd


def test_the_folder_is_split_trained_rolled_out_and_scored_by_the_generic_metrics(folder, workdir):
    res = workdir / "results" / "mine"
    user = config.load({"scale": "ci"})["user"]
    splits = pd.read_csv(res / "dataset" / "splits.csv")
    assert list(splits["id"]) == [f"Run-{i}" for i in range(4)]
    assert list(splits["split"]) == sweep.split_labels(4, user["split"], user["seed"])
    assert list(splits["path"]) == [str(folder / f"Run-{i}.h5") for i in range(4)]
    # R: 2.5 mean diameters of the train split's moving particles, read here from the sims themselves
    train = [h5md.read(p) for p in splits.query("split == 'train'")["path"]]
    radius = np.concatenate([t.radius[~t.kinematic] for t in train]).astype(np.float64).mean()
    stats = json.loads((res / "dataset" / "stats.json").read_text())
    assert stats["connectivity_radius"] == pytest.approx(user["connectivity_diameters"] * 2 * radius, rel=1e-6)
    assert stats["user_data"]["folder"] == str(folder) and stats["n_train_sims"] == len(train) == 2
    test = list(splits.query("split == 'test'")["id"])
    assert [p.stem for p in sorted((res / "rollouts").glob("*.h5"))] == test
    metrics = pd.read_csv(res / "metrics.csv")
    overall = metrics[metrics["sim"] == "all"]
    assert set(overall["metric"]) == GENERIC                        # no scene metric, though the sims are slides
    assert set(metrics["method"]) == {"graphdem", "constant_velocity"}     # no DEM ensemble
    mse = overall[overall["metric"] == "rollout MSE"].set_index("method")["mse"]
    assert all(math.isfinite(mse[m]) and mse[m] > 0 for m in ("graphdem", "constant_velocity"))
    assert set(metrics["split"]) == {"test"} and set(metrics["history"]) == {user["model"]["history"]}
    assert "no DEM ensemble in this evaluation" in (res / "metrics.html").read_text()
    assert (res / "scale.txt").read_text() == "ci\n"
    for stage in ("dataset", "train", "evaluate", *(f"rollout/{i}" for i in test)):
        assert (res / "logs" / f"{stage}.log").is_file() and (res / "timings" / f"{stage}.tsv").is_file()
    assert (res / "plots" / "dataset_sample.png").is_file() and (res / "plots" / "rollout.gif").is_file()


def test_an_unchanged_rerun_does_nothing_and_another_scale_is_refused(folder, workdir):
    for target in (TARGET, "user_data"):                         # the rule of every configured set too
        proc = snakemake(workdir, target, "-n", config_args=(f"user_data={folder}",))
        assert proc.returncode == 0 and "Nothing to be done" in proc.stdout + proc.stderr
    proc = subprocess.run([SNAKEMAKE, TARGET, "-n", "-s", str(ROOT / "workflow" / "Snakefile"), "-d", str(workdir),
                           "--config", f"user_data={folder}"], capture_output=True, text=True)
    assert proc.returncode != 0
    assert "results/mine holds results of scale=ci; this run asks for scale=default" in proc.stdout + proc.stderr


@pytest.mark.parametrize("given, expected", [
    ("{slide: FOLDER}", "config key 'user_data.slide': the name 'slide' is taken by the workflow's results/slide/"),
    ("MISSING", "config key 'user_data' = 'MISSING': no such folder"),
    ("EMPTY", "config key 'user_data' = 'EMPTY': the folder holds no *.h5 file"),
])
def test_a_taken_name_a_missing_or_an_empty_folder_is_refused_before_anything_runs(folder, tmp_path, given,
                                                                                    expected):
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "notes.txt").write_text("no sims here")
    paths = {"FOLDER": str(folder), "MISSING": str(tmp_path / "missing"), "EMPTY": str(empty)}
    for word, path in paths.items():
        given, expected = given.replace(word, path), expected.replace(word, path)
    proc = snakemake(tmp_path / "work", "results/slide/metrics.csv", "-n", config_args=(f"user_data={given}",))
    assert proc.returncode != 0
    assert expected in proc.stdout + proc.stderr
    assert not (tmp_path / "work" / "results").exists()
