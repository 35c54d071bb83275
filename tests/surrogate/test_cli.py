"""`graphdem train` takes the workflow's config keys: --scene, --config FILE and --set KEY=VALUE."""

import json

import pandas as pd
import pytest
import yaml

from generators import config, h5md
from graphdem import cli
from surrogate import checkpoint, contacts
from surrogate import derived as derived_rules
from tests.surrogate import synthetic


def train(tiny, out, *options):
    return cli.main(["train", "--scene", "slide", "--stats", str(tiny["stats_path"]), "--splits",
                     str(tiny["splits"]), "--out-dir", str(out), "--max-steps", "1", "--no-progress", *options])


def test_train_takes_a_config_file_and_set_keys_as_the_workflow_does(tiny_dataset, tmp_path):
    mine = tmp_path / "mine.yaml"
    mine.write_text(yaml.safe_dump({"scale": "ci", "slide": {"model": {"history": 4, "latent": 8},
                                                               "train": {"lr": 0.002, "seed": 3}}}))
    assert train(tiny_dataset, tmp_path / "model", "--config", str(mine), "--set", "slide.train.lr=5e-4",
                 "--set", "slide.model.hidden=16") == 0
    meta = checkpoint.load(tmp_path / "model" / "last.pt")["json"]
    expected = config.load({"scale": "ci", "slide": {"model": {"history": 4, "latent": 8, "hidden": 16},
                                                      "train": {"lr": 5e-4, "seed": 3}}})["slide"]
    assert meta["model"] == expected["model"]
    # the checkpoint keeps the numbers training used: `auto` keys resolved from the stats, their rule beside them
    derived = meta["train"].pop("derived")
    assert set(derived) == {key for key, value in expected["train"].items() if value == "auto"} == \
        {"noise_std", "ema_decay"}
    for key in derived:
        assert isinstance(meta["train"][key], float) and derived[key]["rule"]
        expected["train"][key] = meta["train"][key]
    stats = json.loads(tiny_dataset["stats_path"].read_text())
    assert meta["train"]["noise_std"] == pytest.approx(derived_rules.noise_std(stats, expected["train"]["noise_ratio"]))
    assert meta["train"] == expected["train"]
    assert meta["train"]["lr"] == 5e-4 and meta["model"]["latent"] == 8     # --set wins over the file


@pytest.mark.parametrize("options, message", [
    (["--set", "slide.train.lrate=1e-3"], "unknown config key 'slide.train.lrate'"),
    (["--set", "slide.train.lr"], "--set 'slide.train.lr': expected KEY=VALUE"),
    (["--set", "scale=huge"], "config key 'scale' = 'huge' is not allowed"),
])
def test_a_bad_key_stops_before_training_naming_it(tiny_dataset, tmp_path, capsys, options, message):
    assert train(tiny_dataset, tmp_path / "model", *options) == 1
    assert message in capsys.readouterr().err
    assert not (tmp_path / "model").exists()


def test_a_config_file_that_is_not_a_mapping_is_named(tiny_dataset, tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("- just\n- a list\n")
    assert train(tiny_dataset, tmp_path / "model", "--config", str(bad)) == 1
    assert f"--config {bad}: must hold a mapping of config keys, got list" in capsys.readouterr().err


def test_train_needs_a_scene_or_the_workflows_sections(tmp_path):
    with pytest.raises(SystemExit, match="give --scene"):
        cli.main(["train", "--out-dir", str(tmp_path)])
    with pytest.raises(SystemExit, match="go together"):
        cli.main(["train", "--scene", "slide", "--model-json", "{}", "--out-dir", str(tmp_path)])


def test_contacts_prints_and_writes_the_capped_miss_table_of_a_split(tmp_path, capsys):
    data = synthetic.build(tmp_path)
    out = tmp_path / "contacts.csv"
    cli.main(["contacts", "--splits", str(data["splits"]), "--radius", "1.6", "0.82", "--cap", "4", "2",
              "--out", str(out)])
    printed = capsys.readouterr().out
    assert "2 train sims" in printed and "| 1.6 | 4 |" in printed
    table = pd.read_csv(out)
    assert list(zip(table["connectivity_radius"], table["cap"].fillna(0), strict=True)) == [
        (0.82, 0), (0.82, 2), (0.82, 4), (1.6, 0), (1.6, 2), (1.6, 4)]            # sorted, no cap first
    train = [h5md.read(data["paths"][name]) for name, split in data["split_of"].items() if split == "train"]
    expected = contacts.cap_table([(t.position, t.radius, t.kinematic) for t in train], [0.82, 1.6], [None, 2, 4])
    assert table["missed"].tolist() == [row["missed"] for row in expected]
    assert table["senders_per_receiver"].tolist() == pytest.approx([row["senders_per_receiver"] for row in expected])
    assert table["contacts"].iloc[0] > 50 and table["missed"].iloc[0] > table["missed"].iloc[3]
    with pytest.raises(SystemExit, match="no sim in split 'tset'"):
        cli.main(["contacts", "--splits", str(data["splits"]), "--split", "tset", "--radius", "1.6"])
