"""`graphdem dataset` and `contacts` (surrogate/commands/dataset.py) on the synthetic sims: a sweep table joined
to its sims folder, the train split's statistics written and reported, and the contacts table per radius and cap."""

import json

import pandas as pd
import pytest

from surrogate.commands import dataset

from ...command_line import run
from .. import synthetic


@pytest.fixture(scope="module")
def sims(tmp_path_factory):
    root = tmp_path_factory.mktemp("sims")
    ids = ["syn_00", "syn_01", "syn_02"]
    for i, name in enumerate(ids):
        synthetic.write_sim(root / "sims" / f"{name}.h5", seed=i)
    pd.DataFrame({"id": ids, "split": ["train", "train", "test"]}).to_csv(root / "sweep.csv", index=False)
    return root


def test_a_sweep_table_with_its_sims_folder_makes_the_dataset(sims, tmp_path, capsys):
    argv = ["dataset", "--scene", "slide", "--table", str(sims / "sweep.csv"), "--out-dir", str(tmp_path / "ds"),
            "--connectivity-radius", str(synthetic.RADIUS)]
    with pytest.raises(SystemExit, match="has no path column; give --sims"):
        run(dataset.register, argv)
    run(dataset.register, [*argv, "--sims", str(sims / "sims")])
    splits = pd.read_csv(tmp_path / "ds" / "splits.csv")
    assert list(splits["path"]) == [str(sims / "sims" / f"syn_0{i}.h5") for i in range(3)]
    stats = json.loads((tmp_path / "ds" / "stats.json").read_text())
    assert stats["connectivity_radius"] == synthetic.RADIUS
    counted = stats["neighbour_counts"]
    out = capsys.readouterr().out
    assert (f"neighbours within R = {synthetic.RADIUS:g} on the train split: at most {counted['max']}, "
            f"99th percentile {counted['p99']}") in out


def test_the_contacts_table_has_a_row_per_radius_and_cap(sims, tmp_path, capsys):
    run(dataset.register, ["dataset", "--scene", "slide", "--table", str(sims / "sweep.csv"), "--sims",
                           str(sims / "sims"), "--out-dir", str(tmp_path / "ds"), "--connectivity-radius", "1.6"])
    splits = tmp_path / "ds" / "splits.csv"
    run(dataset.register, ["contacts", "--splits", str(splits), "--radius", "1.6", "0.9", "--cap", "4", "--out",
                           str(tmp_path / "c.csv")])
    table = pd.read_csv(tmp_path / "c.csv")
    assert list(zip(table["connectivity_radius"], table["cap"].fillna(-1), strict=True)) == [
        (0.9, -1), (0.9, 4), (1.6, -1), (1.6, 4)]
    # a larger radius, or no cap, misses no more of the same contacts
    by = table.set_index(["connectivity_radius", table["cap"].fillna(-1)])["missed"]
    assert by[(1.6, -1)] <= by[(0.9, -1)] and by[(1.6, -1)] <= by[(1.6, 4)]
    assert (table["contacts"] == table["contacts"].iloc[0]).all()
    assert "2 train sims of" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="no sim in split 'valid'"):
        run(dataset.register, ["contacts", "--splits", str(splits), "--split", "valid", "--radius", "1.6"])


def test_a_user_folder_makes_the_dataset_with_the_user_sections_defaults(tmp_path, capsys):
    """--user-data FOLDER alone: the config's user split, seed and R rule (2.5 mean diameters of the synthetic
    discs of radius 0.4: 2 m), the plot titled by the folder; flags override each."""
    from generators import config, sweep
    folder = tmp_path / "my-sims"
    for i in range(5):
        synthetic.write_sim(folder / f"run-{i}.h5", seed=i)
    user = config.load()["user"]
    run(dataset.register, ["dataset", "--user-data", str(folder), "--out-dir", str(tmp_path / "ds"),
                           "--min-frames", "7", "--plot", str(tmp_path / "sample.png")])
    splits = pd.read_csv(tmp_path / "ds" / "splits.csv")
    assert list(splits["split"]) == sweep.split_labels(5, user["split"], user["seed"])
    stats = json.loads((tmp_path / "ds" / "stats.json").read_text())
    assert stats["connectivity_radius"] == pytest.approx(user["connectivity_diameters"] * 0.8)
    assert stats["user_data"]["folder"] == str(folder) and (tmp_path / "sample.png").stat().st_size > 10_000
    run(dataset.register, ["dataset", "--user-data", str(folder), "--out-dir", str(tmp_path / "ds2"), "--fractions",
                           "0.4", "0.4", "0.2", "--seed", "9", "--connectivity-radius", "1.5", "--min-frames", "7"])
    stats = json.loads((tmp_path / "ds2" / "stats.json").read_text())
    assert stats["connectivity_radius"] == 1.5 and stats["splits"] == {"train": 2, "valid": 2, "test": 1}
    assert list(pd.read_csv(tmp_path / "ds2" / "splits.csv")["split"]) == sweep.split_labels(5, [0.4, 0.4, 0.2], 9)
    with pytest.raises(ValueError, match=r"run-0.h5: 7 frames; .* at least 8"):
        run(dataset.register, ["dataset", "--user-data", str(folder), "--out-dir", str(tmp_path / "ds3"),
                               "--min-frames", "8"])
    short = tmp_path / "short"
    for i in range(3):
        synthetic.write_sim(short / f"s{i}.h5", seed=i, frames=6)
    with pytest.raises(ValueError, match=r"s0.h5: 6 frames; .* at least 7 \(model.history"):     # K = 6, bundle 1
        run(dataset.register, ["dataset", "--user-data", str(short), "--out-dir", str(tmp_path / "ds3")])
    with pytest.raises(SystemExit, match="--user-data splits its folder itself"):
        run(dataset.register, ["dataset", "--user-data", str(folder), "--table", str(tmp_path / "ds" / "splits.csv"),
                               "--out-dir", str(tmp_path / "ds3")])
    with pytest.raises(SystemExit, match="--table and --connectivity-radius are needed with --scene"):
        run(dataset.register, ["dataset", "--scene", "slide", "--out-dir", str(tmp_path / "ds3")])
