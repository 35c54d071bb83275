import numpy as np

from generators import sweep


def test_same_seed_gives_bit_identical_table(ci_slide, tmp_path):
    a, b = sweep.build("slide", ci_slide), sweep.build("slide", ci_slide)
    a.to_csv(tmp_path / "a.csv", index=False)
    b.to_csv(tmp_path / "b.csv", index=False)
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()


def test_other_seed_gives_other_parameters(ci_slide):
    other = dict(ci_slide, seed=ci_slide["seed"] + 1)
    a, b = sweep.build("slide", ci_slide), sweep.build("slide", other)
    assert not np.allclose(a["weak_base"], b["weak_base"])


def test_adding_sims_keeps_existing_rows(ci_slide):
    small = sweep.build("slide", ci_slide)
    large = sweep.build("slide", dict(ci_slide, n_sims=ci_slide["n_sims"] + 3))
    cols = ["id", "seed", "weak_base", "weak_thickness", "weak_dip", "packing"]
    assert small[cols].equals(large[cols].iloc[: len(small)])


def test_parameters_lie_in_their_ranges_and_every_param_is_a_column(ci_slide):
    table = sweep.build("slide", dict(ci_slide, n_sims=50))
    for name in ("weak_base", "weak_thickness", "weak_dip"):
        lo, hi = ci_slide["sweep"][name]
        assert table[name].between(lo, hi).all()
    for name in ("young", "restitution", "friction", "weak_friction", "frame_interval", "seed", "split"):
        assert name in table.columns


def test_split_is_7_2_1():
    labels = sweep.split_labels(100, [0.7, 0.2, 0.1], seed=3)
    assert (labels.count("train"), labels.count("valid"), labels.count("test")) == (70, 20, 10)
    assert sweep.split_labels(100, [0.7, 0.2, 0.1], seed=3) == labels
    tiny = sweep.split_labels(4, [0.7, 0.2, 0.1], seed=3)
    assert set(tiny) == {"train", "valid", "test"}
