"""`graphdem stability-surrogate` (evaluation/commands/stability.py) on an untrained model of the synthetic sims:
a long rollout per length of the recorded window, its frames, the three precisions, and --runtime-json required."""

import json

import pandas as pd
import pytest

from evaluation.commands import stability
from generators import config

from ...command_line import run
from ...surrogate import saved


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return saved.untrained(tmp_path_factory.mktemp("stability"))


def _argv(data, out, *extra):
    return ["stability-surrogate", "--checkpoint", str(data["checkpoint"]), "--data", str(data["paths"]["syn_03"]),
            "--lengths", "1", "2", "--noise", "0", "--seed", "0", "--max-overlap", "0.5", "--out", str(out), *extra]


def test_long_rollouts_their_frames_and_the_precisions(data, tmp_path):
    runtime = json.dumps(config.load({"scale": "ci"})["slide"]["runtime"])
    run(stability.register, _argv(data, tmp_path / "s.csv", "--runtime-json", runtime,
                                  "--frames-out", str(tmp_path / "f.csv")))
    table, frames = pd.read_csv(tmp_path / "s.csv"), pd.read_csv(tmp_path / "f.csv")
    long = table[table["test"] == "surrogate_long_rollout"].set_index("factor")
    t, k = 7, saved.synthetic.MODEL["history"]                      # the sim's frames, the model's K
    assert list(long.index) == [1.0, 2.0] and list(long["n_frames"]) == [t, 2 * t]
    for factor, row in long.iterrows():
        mine = frames[frames["length"] == factor]
        assert list(mine["frame"]) == list(range(k, int(factor) * t))    # every predicted frame
        assert row["final_kinetic_energy"] == pytest.approx(mine["kinetic_energy"].iloc[-1])
    # no history noise: both lengths roll out the recorded window alike
    assert long.loc[1.0, "mse_recorded"] == long.loc[2.0, "mse_recorded"]
    precision = table[table["test"] == "surrogate_precision"].set_index("setting")
    assert list(precision.index) == ["float64", "float32", "bfloat16"]
    assert precision.loc["float64", "max_difference_vs_float64"] == 0.0
    assert 0 < precision.loc["float32", "max_difference_vs_float64"] < precision.loc["bfloat16",
                                                                                       "max_difference_vs_float64"]


def test_the_runtime_config_is_required(data, tmp_path):
    with pytest.raises(SystemExit, match="graphdem stability-surrogate: --runtime-json is required"):
        run(stability.register, _argv(data, tmp_path / "s.csv"))
    assert not (tmp_path / "s.csv").exists()
