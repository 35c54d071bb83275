"""The config sidecar beside metrics.csv (evaluation/config_sidecar.py): its bytes are the canonical JSON whose
SHA-256 starts with the rows' config_sha, the same digest the checkpoints' config always had; a sidecar of another
config, or none, is refused by name; evaluate.write stages it with the table, and combine carries it."""

import hashlib
import json

import pandas as pd
import pytest

from evaluation import config_sidecar
from evaluation.evaluate import MSE, write
from surrogate import ensemble

from ..command_line import run

META = {"model": {"history": 4, "latent": 16, "name": "Graph-DEM"}, "train": {"seed": 0, "lr": 1e-3},
        "stats": {"dim": 2, "velocity_mean": [0.0, -0.25], "scene": "slide"}, "checkpoint_every": 2}


def test_the_sidecar_is_the_canonical_json_its_sha256_names():
    config = config_sidecar.config_of([META])
    assert config == {k: META[k] for k in ("model", "train", "stats")}           # nothing else of the metadata
    text = config_sidecar.canonical(config)
    assert text == ('{"model": {"history": 4, "latent": 16, "name": "Graph-DEM"}, "stats": {"dim": 2, "scene": '
                    '"slide", "velocity_mean": [0.0, -0.25]}, "train": {"lr": 0.001, "seed": 0}}')
    assert config_sidecar.digest(config) == hashlib.sha256(text.encode()).hexdigest()[:12]
    # the digest the rows always carried: existing config_sha values and the doc tables' stamps keep their meaning
    assert config_sidecar.digest(config) == ensemble.config_digest([META])
    other = {**META, "train": {"seed": 1, "lr": 1e-3}}
    assert config_sidecar.digest(config_sidecar.config_of([META, other])) == ensemble.config_digest([META, other])
    assert config_sidecar.path_of("results/slide/metrics.csv").as_posix() == "results/slide/metrics.config.json"


def test_a_written_sidecar_reads_back_only_under_its_own_digest(tmp_path):
    table = tmp_path / "metrics.csv"
    config = config_sidecar.config_of([META])
    sha = config_sidecar.write(table, config)
    sidecar = tmp_path / "metrics.config.json"
    assert hashlib.sha256(sidecar.read_bytes()).hexdigest().startswith(sha)      # `sha256sum` says the same
    assert config_sidecar.read(table, sha) == config
    sidecar.write_text(json.dumps(config, indent=2))                   # re-indented: the same content, the same config
    assert config_sidecar.read(table, sha) == config
    with pytest.raises(ValueError, match=rf"metrics.config.json: holds the config {sha}, not the config_sha "
                                         r"0123456789ab of metrics.csv"):
        config_sidecar.read(table, "0123456789ab")
    sidecar.write_text(json.dumps({**config, "train": {"seed": 1}}))
    with pytest.raises(ValueError, match=rf"holds the config [0-9a-f]{{12}}, not the config_sha {sha}"):
        config_sidecar.read(table, sha)
    sidecar.write_text("{not json")
    with pytest.raises(ValueError, match="metrics.config.json: not a JSON config sidecar"):
        config_sidecar.read(table, sha)
    sidecar.unlink()
    with pytest.raises(FileNotFoundError, match=rf"metrics.config.json: no such file; the config of metrics.csv "
                                                rf"\(config_sha {sha}\)"):
        config_sidecar.read(table, sha)


def test_write_puts_the_config_beside_the_table_and_only_the_one_its_rows_name(tmp_path):
    config = config_sidecar.config_of([META])
    sha = config_sidecar.digest(config)
    steps = pd.DataFrame({"scene": "slide", "method": "graphdem", "sim": "a", "metric": MSE, "tau": [1, 2],
                          "frame": [4, 5], "time": 0.0, "truth": float("nan"), "prediction": [0.5, 1.5],
                          "blown_up": False, "config_sha": sha})
    table = pd.DataFrame({"metric": [MSE], "unit": ["m^2"], "mse": [1.0], "config_sha": [sha]})
    write(table, steps, tmp_path / "metrics.csv", tmp_path / "steps.csv", config=config)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["metrics.config.json", "metrics.csv", "steps.csv"]
    written = pd.read_csv(tmp_path / "metrics.csv", dtype={"config_sha": str})
    assert "config" not in written.columns and config_sidecar.read(tmp_path / "metrics.csv",
                                                                   written["config_sha"].iloc[0]) == config
    other = config_sidecar.config_of([{**META, "train": {"seed": 7}}])
    for given in (None, other):
        with pytest.raises(ValueError, match=rf"other.csv: its rows name config_sha {sha}, and "):
            write(table, steps, tmp_path / "other.csv", None, config=given)
    assert not (tmp_path / "other.csv").exists() and not (tmp_path / "other.config.json").exists()


def test_combine_carries_the_one_config_its_tables_name(tmp_path, capsys):
    from evaluation.commands import evaluate
    config = config_sidecar.config_of([META])
    sha = config_sidecar.write(tmp_path / "k2.csv", config)
    for k in (2, 6):
        pd.DataFrame({"metric": [MSE], "history": [k], "mse": [0.5], "config_sha": [sha]}).to_csv(
            tmp_path / f"k{k}.csv", index=False)
    run(evaluate.register, ["combine", "--tables", str(tmp_path / "k2.csv"), str(tmp_path / "k6.csv"),
                            "--out", str(tmp_path / "all.csv")])
    assert config_sidecar.read(tmp_path / "all.csv", sha) == config
    assert f"config {sha}: {tmp_path / 'all.config.json'}" in capsys.readouterr().out
    pd.DataFrame({"metric": [MSE], "history": [6], "mse": [0.5], "config_sha": ["0123456789ab"]}).to_csv(
        tmp_path / "k6.csv", index=False)
    run(evaluate.register, ["combine", "--tables", str(tmp_path / "k2.csv"), str(tmp_path / "k6.csv"),
                            "--out", str(tmp_path / "two.csv")])
    assert f"the rows name 2 configs ({sha}, 0123456789ab): no sidecar beside" in capsys.readouterr().out
    assert not (tmp_path / "two.config.json").exists()
