"""`graphdem train`'s sections (surrogate/commands/train.py): the model and train config of a scene's resolved
config or of the workflow's resolved sections, never both, the device, and the files each defaults to."""

from pathlib import Path

import pytest

from generators import config
from surrogate.commands import train

from ...command_line import parse


def _sections(*argv):
    return train.sections(parse(train.register, ["train", *argv]))


def test_a_scene_s_sections_come_from_its_resolved_config_and_its_results_folder():
    model, train_cfg, device, stats, splits, out_dir = _sections("--scene", "slide", "--set", "scale=ci",
                                                                 "--set", "slide.train.lr=0.004")
    expected = config.load({"scale": "ci", "slide": {"train": {"lr": 0.004}}})
    assert model == expected["slide"]["model"] and train_cfg == expected["slide"]["train"]
    assert train_cfg["lr"] == 0.004 and device == expected["device"]
    where = Path("results") / "slide"
    assert (stats, splits, out_dir) == (where / "dataset/stats.json", where / "dataset/splits.csv", where / "model")
    assert _sections("--scene", "slide", "--device", "cpu", "--out-dir", "elsewhere")[2:] == (
        "cpu", where / "dataset/stats.json", where / "dataset/splits.csv", Path("elsewhere"))


def test_the_workflow_s_sections_replace_the_scene_and_name_every_file():
    got = _sections("--model-json", '{"history": 3}', "--train-json", '{"lr": 0.1}', "--stats", "s.json",
                    "--splits", "t.csv", "--out-dir", "m")
    assert got == ({"history": 3}, {"lr": 0.1}, "auto", Path("s.json"), Path("t.csv"), Path("m"))


def test_user_data_trains_with_the_user_section_into_its_folders_results(tmp_path, capsys):
    """--user-data FOLDER: the config's user section, the results of the folder's name (docs/user-data.md)."""
    folder = tmp_path / "my-sims"
    folder.mkdir()
    model, train_cfg, device, stats, splits, out_dir = _sections("--user-data", str(folder), "--set", "scale=ci",
                                                                 "--set", "user.train.lr=0.002")
    expected = config.load({"scale": "ci", "user": {"train": {"lr": 0.002}}})["user"]
    assert model == expected["model"] and train_cfg == expected["train"] and train_cfg["lr"] == 0.002
    assert model["message_passing"] == 2 and train_cfg["noise_std"] == "auto"       # the ci preset, derived noise
    where = Path("results") / "my-sims"
    assert (stats, splits, out_dir) == (where / "dataset/stats.json", where / "dataset/splits.csv", where / "model")
    with pytest.raises(SystemExit):
        _sections("--user-data", str(folder), "--scene", "slide")
    assert "argument --scene: not allowed with argument --user-data" in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    ([], "give --scene"),
    (["--model-json", "{}"], "--model-json and --train-json .* go together"),
    (["--model-json", "{}", "--train-json", "{}", "--scene", "slide"],
     "replace --scene, --benchmark or --user-data, --config and --set"),
    (["--model-json", "{}", "--train-json", "{}", "--stats", "s.json"], "--stats, --splits and --out-dir are needed"),
])
def test_sections_given_two_ways_or_half_are_refused(argv, message):
    with pytest.raises(SystemExit, match=message):
        _sections(*argv)
