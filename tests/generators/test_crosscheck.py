"""The engine cross-check on synthetic collapse deposits whose final heights differ by a known amount between two
engines: the means, spreads, combined standard error and verdict of each metric, the chaos reruns' difference,
the refusals, a metric undefined in some sims, and the transfer table."""

import math

import numpy as np
import pandas as pd
import pytest

from generators import crosscheck, h5md
from generators.scenes import collapse

# A collapse deposit (generators/scenes/collapse.py): a floor of two fixed discs (radius 0.25, top at 0.5) and four
# grains of radius 0.5 in bins 0-3 of width 1; L0 = 2, so every deposit's runout is 4 - 2 = 2. Raising the grain
# of bin 1 by ``lift`` makes the final height 1.0 + lift (its top 1.5 + lift, above the floor's 0.5).
FLOOR = np.array([[0.25, 0.25], [0.7, 0.25]])
GRAINS = np.array([[0.5, 1.0], [1.5, 1.0], [2.5, 1.0], [3.5, 1.0]])


def _write(path, lift: float, engine: str) -> None:
    final = GRAINS + [[0.0, 0.0], [0.0, lift], [0.0, 0.0], [0.0, 0.0]]
    position = np.stack([np.vstack([FLOOR, GRAINS]), np.vstack([FLOOR, final])])
    kinematic = np.arange(6) < 2
    h5md.write(path, h5md.Trajectory(
        position=position, time=np.array([0.0, 0.1]), step=np.array([0, 100]),
        species=np.where(kinematic, collapse.FLOOR, collapse.GRAIN), radius=np.where(kinematic, 0.25, 0.5),
        mass=np.ones(6), kinematic=kinematic, box_lower=np.zeros(2), box_upper=np.array([10.0, 5.0]),
        parameters={"column_width": 2.0, "floor_radius": 0.25, "engine": engine}))


def _sims(root, engine: str, lifts, ids=("c0", "c1", "c2")) -> list:
    root.mkdir(parents=True, exist_ok=True)
    for sim, lift in zip(ids, lifts, strict=True):
        _write(root / f"{sim}.h5", lift, engine)
    return [root / f"{sim}.h5" for sim in ids]


@pytest.fixture
def engines(tmp_path) -> dict:
    # final heights: lammps 1.0, 1.1, 1.2 (mean 1.1, std 0.1); yade 1.3, 1.4, 1.5 (mean 1.4, std 0.1)
    return {"lammps": _sims(tmp_path / "lammps", "lammps", [0.0, 0.1, 0.2]),
            "yade": _sims(tmp_path / "yade", "yade", [0.3, 0.4, 0.5])}


def test_final_values_are_each_metric_at_each_sim_s_last_frame(engines):
    values = crosscheck.final_values("collapse", engines["lammps"])
    assert list(values["sim"]) == ["c0", "c1", "c2"]
    np.testing.assert_allclose(values["Height"], [1.0, 1.1, 1.2])
    np.testing.assert_allclose(values["Runout"], [2.0, 2.0, 2.0])


def test_a_difference_beyond_the_tolerance_and_the_standard_error_fails(engines):
    table = crosscheck.compare("collapse", engines, tolerance=0.05)
    assert list(table.columns) == list(crosscheck.COLUMNS) and list(table["metric"]) == ["Runout", "Height"]
    table = table.set_index("metric")
    h = table.loc["Height"]
    assert (h["engine_a"], h["engine_b"], h["n_a"], h["n_b"]) == ("lammps", "yade", 3, 3)
    assert (h["mean_a"], h["mean_b"]) == (pytest.approx(1.1), pytest.approx(1.4))
    assert (h["std_a"], h["std_b"]) == (pytest.approx(0.1), pytest.approx(0.1))
    se = math.sqrt(0.1**2 / 3 + 0.1**2 / 3)                          # 0.0816 > 0.05 x 1.4 = 0.07
    assert h["combined_se"] == pytest.approx(se) and h["allowed"] == pytest.approx(se)
    assert h["rel_diff"] == pytest.approx(0.3 / 1.4)
    assert h["pass"] is not None and not h["pass"]                   # 0.3 > 0.0816
    assert h["unit"] == "m" and h["note"] == ""
    r = table.loc["Runout"]                                            # the same runout in every sim
    assert r["rel_diff"] == 0.0 and r["combined_se"] == 0.0 and bool(r["pass"])
    assert table["chaos_engine"].isna().all() and table["chaos_rel_diff"].isna().all()


def test_a_tolerance_above_the_difference_passes(engines):
    h = crosscheck.compare("collapse", engines, tolerance=0.25).set_index("metric").loc["Height"]
    assert h["allowed"] == pytest.approx(0.25 * 1.4) and bool(h["pass"])       # 0.3 <= 0.35


def test_chaos_reruns_give_the_engine_s_own_difference(engines, tmp_path):
    chaos = _sims(tmp_path / "chaos", "lammps", [0.1, 0.2, 0.3])       # mean height 1.2 against lammps' 1.1
    table = crosscheck.compare("collapse", engines, 0.05, chaos=chaos).set_index("metric")
    assert set(table["chaos_engine"]) == {"lammps"}
    assert table.loc["Height", "chaos_rel_diff"] == pytest.approx(0.1 / 1.2)
    assert table.loc["Runout", "chaos_rel_diff"] == 0.0
    with pytest.raises(ValueError, match="chaos reruns must be the same sims"):
        crosscheck.compare("collapse", engines, 0.05, chaos=chaos[:2])
    other = _sims(tmp_path / "other", "fakedem", [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"in one of \['lammps', 'yade'\]"):
        crosscheck.compare("collapse", engines, 0.05, chaos=other)


def test_different_sims_too_few_sims_or_one_engine_are_refused(engines, tmp_path):
    with pytest.raises(ValueError, match="compares two engines or more"):
        crosscheck.compare("collapse", {"lammps": engines["lammps"]}, 0.05)
    with pytest.raises(ValueError, match="the engines ran different sims"):
        crosscheck.compare("collapse", {"lammps": engines["lammps"], "yade": engines["yade"][:2]}, 0.05)
    two = {name: files[:1] for name, files in engines.items()}
    with pytest.raises(ValueError, match="at least 2 sims per engine for a spread, got 1"):
        crosscheck.compare("collapse", two, 0.05)


def test_a_metric_undefined_in_some_sims_leaves_them_out_and_says_so():
    a = pd.DataFrame({"Height": [1.0, np.nan, 1.2, 1.4]})
    b = pd.DataFrame({"Height": [1.0, 1.2, 1.4, 1.6]})
    row = crosscheck._row("collapse", "Height", ("lammps", a), ("yade", b), 0.05, (None, None))
    assert (row["n_a"], row["n_b"]) == (3, 4) and row["mean_a"] == pytest.approx(1.2)
    assert row["note"] == "undefined at the last frame in 1 lammps and 0 yade sims"
    few = crosscheck._row("collapse", "Height", ("lammps", pd.DataFrame({"Height": [np.nan, np.nan, 1.0]})),
                          ("yade", b), 0.05, (None, None))
    assert few["pass"] is None and few["n_a"] == 1 and "fewer than 2 values in an engine, not compared" in few["note"]


def test_transfer_puts_one_model_s_rollout_mse_on_both_engines_side_by_side():
    def table(mse):
        return pd.DataFrame({"metric": ["rollout MSE", "rollout MSE", "Runout"], "sim": ["all", "c0", "all"],
                             "method": "graphdem", "history": 6, "mse": [mse, 9.0, 9.0], "n_sims": 3})

    out = crosscheck.transfer(table(0.5), table(2.0), "lammps", "yade")
    assert out.to_dict("records") == [
        {"trained_on": "lammps", "scored_on": "lammps", "method": "graphdem", "history": 6, "rollout_mse": 0.5,
         "sims": 3},
        {"trained_on": "lammps", "scored_on": "yade", "method": "graphdem", "history": 6, "rollout_mse": 2.0,
         "sims": 3}]
