"""User data (generators/user_data.py): a folder of H5MD sims named and checked when the config is read, and split
by the sweep's seeded rule. The checks read no file, so the folders here hold empty *.h5 files."""

from pathlib import Path

import pytest

from generators import config, sweep, user_data
from generators.errors import ConfigError


def folder(root: Path, names: list[str]) -> Path:
    root.mkdir(parents=True, exist_ok=True)
    for name in names:
        (root / name).write_bytes(b"")
    return root


def sims(root: Path, n: int) -> Path:
    return folder(root, [f"run_{i:02d}.h5" for i in range(n)])


def test_the_split_is_the_sweeps_seeded_rule_over_the_sims_sorted_by_name(tmp_path):
    root = folder(tmp_path / "mine", [f"run_{i:02d}.h5" for i in (9, 3, 0, 1, 2, 4, 5, 6, 7, 8)]
                  + [".run_10.h5.tmp-1.h5", "notes.txt"])
    table = user_data.split_table(root, [0.7, 0.2, 0.1], 5)
    assert list(table["id"]) == [f"run_{i:02d}" for i in range(10)]            # hidden and other files left out
    assert list(table["path"]) == [str(root / f"run_{i:02d}.h5") for i in range(10)]
    assert list(table["split"]) == sweep.split_labels(10, [0.7, 0.2, 0.1], 5)
    assert table["split"].value_counts().to_dict() == {"train": 7, "valid": 2, "test": 1}
    assert user_data.split_table(root, [0.7, 0.2, 0.1], 5).equals(table)     # the same folder, the same table
    other = user_data.split_table(root, [0.7, 0.2, 0.1], 6)
    assert list(other["split"]) != list(table["split"])
    assert other["split"].value_counts().to_dict() == {"train": 7, "valid": 2, "test": 1}


def test_a_plain_path_is_one_set_named_by_the_folder(tmp_path):
    root = sims(tmp_path / "my-sims", 3)
    assert user_data.normalise(str(root) + "/") == {"my-sims": str(root) + "/"}
    assert user_data.normalise({"a": "x"}) == {"a": "x"}
    resolved = config.load({"scale": "ci", "user_data": str(root)})
    assert resolved["user_data"] == {"my-sims": str(root)}
    assert config.load({"user_data": {"mine": str(root)}})["user_data"] == {"mine": str(root)}
    assert config.load()["user_data"] == {}


@pytest.mark.parametrize("name, taken", [("slide", "slide"), ("slide_samer", "slide_samer"),
                                         ("crosscheck", "crosscheck")])
def test_a_name_a_scene_or_benchmark_has_is_refused(tmp_path, name, taken):
    root = sims(tmp_path / "data", 3)
    with pytest.raises(ConfigError, match=rf"config key 'user_data.{name}': the name '{taken}' is taken by the "
                                          rf"workflow's results/{taken}/; allowed: any other name"):
        config.load({"user_data": {name: str(root)}})
    plain = sims(tmp_path / name, 3)                   # a folder whose basename is taken
    with pytest.raises(ConfigError, match=rf"config key 'user_data': the name '{taken}' is taken"):
        config.load({"user_data": str(plain)})


def test_a_missing_or_empty_folder_or_unusable_file_names_are_refused(tmp_path):
    with pytest.raises(ConfigError, match=r"config key 'user_data' = '.*nowhere': no such folder"):
        config.load({"user_data": str(tmp_path / "nowhere")})
    empty = folder(tmp_path / "empty", ["readme.txt", ".hidden.h5"])
    with pytest.raises(ConfigError, match=r"config key 'user_data.e' = '.*empty': the folder holds no \*.h5 file"):
        config.load({"user_data": {"e": str(empty)}})
    odd = folder(tmp_path / "odd", ["a.h5", "b.h5", "two words.h5", "$(x).h5"])
    with pytest.raises(ConfigError, match=r"the file name '\$\(x\).h5' \(and 1 more\) is no usable sim id"):
        config.load({"user_data": str(odd)})
    with pytest.raises(ConfigError, match=r"config key 'user_data.x y': 'x y' is not a results name"):
        config.load({"user_data": {"x y": str(sims(tmp_path / "ok", 3))}})


def test_every_split_needs_a_sim(tmp_path):
    two = sims(tmp_path / "two", 2)
    with pytest.raises(ConfigError, match=r"its 2 sims split by 'user.split' = \[0.7, 0.2, 0.1\] leave the valid and "
                                          r"test split empty \(\{'train': 2, 'valid': 0, 'test': 0\}\)"):
        config.load({"user_data": str(two)})
    three = sims(tmp_path / "three", 3)
    assert config.load({"user_data": str(three)})["user_data"] == {"three": str(three)}
    with pytest.raises(ConfigError, match=r"leave the valid split empty"):
        config.load({"user_data": str(three), "user": {"split": [0.9, 0.0, 0.1]}})
    with pytest.raises(ConfigError, match=r"config key 'user.split' = \[0.5, 0.2, 0.1\] must sum to 1"):
        config.load({"user_data": str(three), "user": {"split": [0.5, 0.2, 0.1]}})
    with pytest.raises(ConfigError, match=r"three: the split \[0.5, 0.6, -0.1\] is not allowed; allowed: three "
                                          r"fractions"):
        user_data.split_table(three, [0.5, 0.6, -0.1], 0)


def test_user_data_of_another_type_and_the_user_section_are_validated_by_name():
    with pytest.raises(ConfigError, match=r"config key 'user_data' = 5 is not allowed: it must be a string or a "
                                          r"mapping"):
        config.load({"user_data": 5})
    with pytest.raises(ConfigError, match=r"config key 'user.connectivity_radius' = 'big' is not allowed"):
        config.load({"user": {"connectivity_radius": "big"}})
    with pytest.raises(ConfigError, match=r"unknown config key 'user.radius'"):
        config.load({"user": {"radius": 2.0}})
    resolved = config.load({"scale": "ci"})["user"]
    assert resolved["connectivity_radius"] == "auto" and resolved["model"]["message_passing"] == 2
    assert config.load({"user": {"connectivity_radius": 3.5}})["user"]["connectivity_radius"] == 3.5
