"""Faults leave nothing half-written: `graphdem evaluate` under a file-size limit (``ulimit -f``, EFBIG) exits 1
with one line naming the file it could not write, leaves every previous output byte for byte and no temporary or
partial new one; its outputs appear together or not at all; and text from file names or sim ids (``$\\alpha$_x``, a
malformed ``$\\frac{$_y``) is drawn as typed, never read as mathtext, in every plot that shows it."""

import os
import resource
import shutil
import subprocess
import sys

import matplotlib.text
import numpy as np
import pandas as pd
import pytest

from evaluation import plots
from generators import plots as generator_plots
from graphdem import cli
from surrogate import checkpoint

from .surrogate import saved, synthetic

NAMES = ("$\\alpha$_x", "$\\frac{$_y")          # balanced markup, and markup matplotlib cannot parse
OUTPUTS = ("metrics.csv", "new/steps.csv", "metrics.html", "plots/metrics_over_frames.png", "plots/rollout.gif")


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    """An untrained Graph-DEM checkpoint (with its training config, as train writes it) and a folder of two sims
    named with mathtext markup."""
    root = tmp_path_factory.mktemp("faults")
    data = saved.untrained(root)
    checkpoint.save(data["checkpoint"], {"model": data["simulator"].state_dict(), "json": {
        "stats": data["stats"], "model": synthetic.MODEL, "train": synthetic.TRAIN}})
    sims = root / "named"
    sims.mkdir()
    for name, source in zip(NAMES, ("syn_02", "syn_03"), strict=True):
        shutil.copy(data["paths"][source], sims / f"{name}.h5")
    return data["checkpoint"], sims


def _argv(model, out) -> list[str]:
    ckpt, sims = model
    return ["evaluate", "--checkpoint", str(ckpt), "--data", str(sims), "--history", "3", "--no-progress",
            "--out", str(out / OUTPUTS[0]), "--per-step", str(out / OUTPUTS[1]),
            "--table-html", str(out / OUTPUTS[2]), "--plots", str(out / "plots"), "--animate", NAMES[1]]


def _limited(argv: list[str], limit: int) -> subprocess.CompletedProcess:
    """`graphdem ARGV` in a process that may write files of at most ``limit`` bytes."""
    def cap():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return subprocess.run([sys.executable, "-m", "graphdem", *argv], capture_output=True, text=True,
                          preexec_fn=cap, timeout=300)


def _tree(folder) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


def test_sims_named_with_markup_are_evaluated_and_plotted_as_named(model, tmp_path):
    assert cli.main(_argv(model, tmp_path)) == 0
    assert _tree(tmp_path) == ["metrics.config.json", "metrics.csv", "metrics.html", "new", "new/steps.csv", "plots",
                               "plots/metrics_over_frames.png", "plots/rollout.gif"]
    table = pd.read_csv(tmp_path / "metrics.csv")
    assert set(NAMES) < set(table["sim"])
    assert (tmp_path / "plots" / "rollout.gif").read_bytes()[:6] == b"GIF89a"


def test_a_file_size_limit_leaves_every_previous_output_and_names_the_file(model, tmp_path):
    previous = [name for name in OUTPUTS if not name.startswith("new/")]
    for name in previous:                       # the previous run's outputs, told apart by their content
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_text(f"previous {name}")
    # 20 kB: the tables and the HTML page fit, the first plot does not
    done = _limited(_argv(model, tmp_path), 20_000)
    png = tmp_path / "plots" / "metrics_over_frames.png"
    assert done.returncode == 1
    assert done.stderr.splitlines()[-1:] == [f"graphdem evaluate: error: {png}: cannot be written: File too large"]
    assert "Traceback" not in done.stderr and len(done.stderr.strip().splitlines()) == 1
    # no temporary; no new per-step table (written before the plot failed) nor the folder made for it
    assert _tree(tmp_path) == ["metrics.csv", "metrics.html", "plots", "plots/metrics_over_frames.png",
                               "plots/rollout.gif"]
    assert all((tmp_path / name).read_text() == f"previous {name}" for name in previous)


def test_text_from_data_is_drawn_as_typed():
    for name in (*NAMES, "a$b", "cost in $ and \\$"):
        text = matplotlib.text.Text(text=plots.plain(name))
        assert text._preprocess_math(text.get_text()) == (name, False)        # no mathtext, the name as typed


def test_every_plot_that_shows_a_name_draws_malformed_markup(tmp_path):
    bad = NAMES[1]
    position = np.array([[[1.0, 1.0], [2.0, 1.0]], [[1.0, 2.0], [2.0, 2.5]]])
    generator_plots.first_last(tmp_path / "first_last.png", position, np.full(2, 0.3), np.array([0, 1]),
                               np.array([0.0, 0.5]), np.zeros(2), np.full(2, 4.0), f"sim {bad}",
                               labels={0: bad, 1: "grain"})
    frames = pd.DataFrame({"sim": bad, "length": 2, "frame": [0, 1, 2], "kinetic_energy": [1.0, 2.0, 3.0],
                           "in_envelope": [True, True, False], "max_overlap": 0.01, "p99_overlap": 0.005})
    plots.stability(frames, tmp_path / "stability.png", bad)
    contenders = pd.DataFrame({"contender": [bad, f"dem {bad}"], "kind": ["surrogate", "dem"], "mse": [0.5, 0.0],
                               "seconds_per_rollout": [1.0, 10.0], "on_pareto_front": [True, True]})
    plots.pareto(contenders, tmp_path / "pareto.png", bad)
    steps = pd.DataFrame({"sim": "all", "method": ["graphdem", bad], "metric": bad, "tau": 1, "time": 0.1,
                          "truth": 1.0, "prediction": [1.5, 2.0]})
    plots.metrics_over_frames(steps, tmp_path / "metrics.png", bad)
    truth = np.zeros((2, 2, 2)) + [[1.0, 1.0], [2.0, 2.0]]
    plots.animation(tmp_path / "a.gif", truth, truth, np.full(2, 0.3), np.array([0, 1]), np.array([0.0, 0.1]),
                    np.zeros(2), np.full(2, 3.0), 1, bad, {0: bad})
    assert sorted(os.listdir(tmp_path)) == ["a.gif", "first_last.png", "metrics.png", "pareto.png",
                                            "stability.png"]
