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
