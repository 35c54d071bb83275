"""Where the surrogate pays, per test sim: speed-ups and break-even sub-steps from the contenders' per-sim timings,
checked by hand."""

import json

import pandas as pd
import pytest

from evaluation import performance_map


def _dem(seconds_per_frame: float, steps: int) -> dict:
    return {"seconds_per_frame": seconds_per_frame, "steps_per_frame": steps,
            "seconds_per_dem_step": seconds_per_frame / steps, "particles": 1100, "moving": 490}


def table() -> pd.DataFrame:
    """Two sims: a cheap one (100 sub-steps per frame at the fast step) and a costly one (800); the surrogate takes
    40 ms per frame on both. The reference runs 25x the fast step's sub-steps."""
    surrogate = {"a": {"seconds_per_frame": 0.04, "particles": 1100, "moving": 490},
                 "b": {"seconds_per_frame": 0.04, "particles": 1100, "moving": 490}}
    fast = {"a": _dem(0.02, 100), "b": _dem(0.16, 800)}
    reference = {"a": _dem(0.5, 2500), "b": _dem(4.0, 20000)}
    return pd.DataFrame([
        {"contender": "reference", "kind": "dem", "per_sim": json.dumps(reference)},
        {"contender": "dt_50pct", "kind": "dem", "per_sim": json.dumps(fast)},
        {"contender": "soft", "kind": "dem", "per_sim": json.dumps({"a": _dem(0.01, 20), "b": _dem(0.02, 40)})},
        {"contender": "graphdem", "kind": "surrogate", "matched_dem": "dt_50pct", "matched_dem_by_mse": "dt_50pct",
         "per_sim": json.dumps(surrogate)},
    ])


def test_speedup_and_break_even_per_sim():
    sims = performance_map.sim_map(table(), "graphdem", "reference")
    assert list(sims.columns) == list(performance_map.COLUMNS)
    matched = sims[sims["match"] == "as accurate"].set_index("sim")
    # 20 ms against 40 ms: half as fast; 160 ms against 40: 4x. The break-even: 40 ms / 0.2 ms per step = 200
    assert matched.loc["a", "speedup"] == pytest.approx(0.5) and matched.loc["b", "speedup"] == pytest.approx(4.0)
    assert list(matched["break_even_steps"]) == pytest.approx([200.0, 200.0])
    assert list(matched["pays"]) == [False, True]
    # the speed-up is the sub-steps over the break-even: the map's line
    assert list(matched["speedup"]) == pytest.approx(list(matched["dem_steps_per_frame"] / matched["break_even_steps"]))
    reference = sims[sims["match"] == "reference"].set_index("sim")
    assert list(reference["speedup"]) == pytest.approx([12.5, 100.0]) and reference["pays"].all()
    assert list(matched["dem_ms_per_frame"]) == pytest.approx([20.0, 160.0])
    assert set(sims["match"]) == {"as accurate", "as accurate by MSE", "reference"}     # nothing timed: no fastest


def test_the_fastest_dem_whatever_its_error_stands_beside_the_matches():
    t = table()
    t["seconds_per_rollout"] = [10.0, 1.8, 0.3, 0.8]           # soft: the fastest DEM, not as accurate
    t["stable"] = True
    sims = performance_map.sim_map(t, "graphdem", "reference")
    fastest = sims[sims["match"] == performance_map.FASTEST].set_index("sim")
    assert (fastest["dem_contender"] == "soft").all()
    assert list(fastest["speedup"]) == pytest.approx([0.25, 0.5])
    row = performance_map.pays_row("shear", sims)
    assert row["match"] == "as accurate" and row["fastest_contender"] == "soft"
    assert row["speedup_vs_fastest"] == pytest.approx(0.375)


def test_a_missing_match_has_no_rows():
    t = table()
    t.loc[t["contender"] == "graphdem", "matched_dem"] = float("nan")       # no DEM as accurate on every measure
    sims = performance_map.sim_map(t, "graphdem", "reference")
    assert set(sims["match"]) == {"as accurate by MSE", "reference"}


def test_a_table_without_per_sim_timings_is_refused_by_name():
    t = table()
    t.loc[t["contender"] == "dt_50pct", "per_sim"] = float("nan")
    with pytest.raises(ValueError, match="contender 'dt_50pct' has no per_sim timings"):
        performance_map.sim_map(t, "graphdem", "reference")
    with pytest.raises(ValueError, match="no surrogate contender 'compiled'"):
        performance_map.sim_map(table(), "compiled", "reference")


def test_the_map_plot_is_written(tmp_path):
    from evaluation import plots
    path = plots.performance_map(performance_map.sim_map(table(), "graphdem", "reference"), tmp_path / "map.png",
                                 "test")
    assert path.stat().st_size > 1000


def test_the_map_table_says_where_it_pays():
    from evaluation.doc_tables import kinds
    text = kinds.sim_map(performance_map.sim_map(table(), "graphdem", "reference"))
    lines = text.splitlines()
    assert lines[0].startswith("| DEM compared | DEM contender | sim |")
    assert "| as accurate | dt_50pct | a | 1100 (490) | 100 | 20 | 40 | 0.5x | 200 | no |" in lines
    assert "| as accurate | dt_50pct | b | 1100 (490) | 800 | 160 | 40 | 4x | 200 | yes |" in lines


def test_the_pays_row_takes_the_closest_comparison_and_the_medians():
    sims = performance_map.sim_map(table(), "graphdem", "reference")
    row = performance_map.pays_row("shear", sims)
    assert row["match"] == "as accurate" and row["dem_contender"] == "dt_50pct" and row["sims"] == 2
    assert row["speedup"] == pytest.approx(2.25) and (row["speedup_min"], row["speedup_max"]) == (0.5, 4.0)
    assert row["dem_steps_per_frame"] == 450 and row["break_even_steps"] == pytest.approx(200.0)
    assert row["verdict"] == "pays on 1 of 2 sims"
    reference_only = sims[sims["match"] == "reference"]
    assert performance_map.pays_row("x", reference_only)["verdict"] == "pays"
    assert performance_map.pays_row("x", sims[(sims["match"] == "as accurate") & (sims["sim"] == "a")])["verdict"] \
        == "does not pay"


def test_the_pays_table_has_a_row_per_scene_and_refuses_an_empty_map():
    sims = performance_map.sim_map(table(), "graphdem", "reference")
    pays = performance_map.pays_table({"slide": sims, "shear": sims})
    assert list(pays["scene"]) == ["slide", "shear"]
    with pytest.raises(ValueError, match="performance map of 'meteorite' has no rows"):
        performance_map.pays_table({"meteorite": sims.iloc[:0]})
    from evaluation.doc_tables import kinds
    text = kinds.pays(pays)
    assert "| slide | pays on 1 of 2 sims | 2.25x [0.5, 4] | dt_50pct (as accurate) | 40 / 90 |" in text
    assert "450 DEM sub-steps per frame (100-800) against a break-even of 200" in text
