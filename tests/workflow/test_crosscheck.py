"""The cross-check stage at ci scale: every scene's sweep rows run in both engines into the same H5MD
layout, the comparison table, and a model scored on the other engine's test sims."""

import math

import numpy as np
import pandas as pd
import pytest

from evaluation import config_sidecar
from generators import config, crosscheck, h5md, scenes

pytestmark = pytest.mark.engine


def test_every_scene_runs_the_same_rows_in_both_engines(ci_results):
    for scene in scenes.names():
        table = pd.read_csv(ci_results / "crosscheck" / f"{scene}.csv")
        main = scenes.get(scene)
        ids = sorted(p.stem for p in (ci_results / scene / "sims").glob("*.h5"))
        assert set(table["engine_a"]) | set(table["engine_b"]) == {"lammps", "yade"}
        assert list(table["metric"]) == list(crosscheck.metric_names(scene))      # shear: + the DEM's peak stress
        engines = sorted(p.name for p in (ci_results / "crosscheck" / scene).iterdir()
                         if (p / "sims").is_dir() and p.name != "chaos")
        configured = config.load({"scale": "ci"})[scene]["engine"]
        assert engines == [{"lammps": "yade", "yade": "lammps"}[configured]]      # the other engine only
        crossed = sorted(p.stem for p in (ci_results / "crosscheck" / scene / engines[0] / "sims").glob("*.h5"))
        assert crossed == ids and len(ids) >= 3
        a, b = (h5md.read(ci_results / scene / "sims" / f"{ids[0]}.h5"),
                h5md.read(ci_results / "crosscheck" / scene / engines[0] / "sims" / f"{ids[0]}.h5"))
        assert {a.parameters["engine"], b.parameters["engine"]} == {"lammps", "yade"}
        # the same layout, particles, species and kinematic set; the same recorded times
        assert a.position.shape == b.position.shape and a.dim == main.dim
        np.testing.assert_array_equal(a.species, b.species)
        np.testing.assert_array_equal(a.kinematic, b.kinematic)
        np.testing.assert_allclose(a.time - a.time[0], b.time - b.time[0], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(a.mass, b.mass, rtol=1e-9)              # the 2D disc mass in YADE too


def test_table_verdicts_follow_the_tolerance_rule(ci_results):
    table = pd.read_csv(ci_results / "crosscheck.csv")
    assert sorted(set(table["scene"])) == sorted(scenes.names())
    judged = table[table["pass"].notna()]
    assert len(judged) >= len(scenes.names())
    for _, row in judged.iterrows():
        scale = max(abs(row["mean_a"]), abs(row["mean_b"]))
        se = math.sqrt(row["std_a"] ** 2 / row["n_a"] + row["std_b"] ** 2 / row["n_b"])
        assert row["combined_se"] == pytest.approx(se)
        assert row["allowed"] == pytest.approx(max(row["tolerance"] * scale, se))
        assert bool(row["pass"]) == (abs(row["mean_a"] - row["mean_b"]) <= row["allowed"])
    # the shear's soil follows the box the same way in both engines
    shear = table[(table["scene"] == "shear") & (table["metric"] == "Mean x")].iloc[0]
    assert shear["pass"] and shear["rel_diff"] < 0.01
    peak = table[(table["scene"] == "shear") & (table["metric"] == "Peak shear stress")].iloc[0]
    assert peak["mean_a"] > 0 and peak["mean_b"] > 0 and peak["unit"] == "Pa"


def test_transfer_scores_one_model_on_both_engines(ci_results):
    for scene in ("slide", "shear"):
        table = pd.read_csv(ci_results / "crosscheck" / f"{scene}_transfer.csv")
        assert set(table["scored_on"]) == {"lammps", "yade"}
        assert set(table["trained_on"]) == {config.load({"scale": "ci"})[scene]["engine"]}
        assert np.isfinite(table["rollout_mse"]).all() and (table["rollout_mse"] > 0).all()
        assert set(table["method"]) >= {"graphdem", "constant_velocity"}
        other = "yade" if config.load({"scale": "ci"})[scene]["engine"] == "lammps" else "lammps"
        metrics = ci_results / "crosscheck" / scene / f"transfer_{other}_metrics.csv"
        sha = pd.read_csv(metrics)["config_sha"].iloc[0]
        assert config_sidecar.read(metrics, sha)["model"]      # the declared sidecar, its digest the rows' sha


def test_compare_refuses_different_rows_and_reports_undefined_metrics(ci_results, tmp_path):
    scene = "meteorite"
    files = sorted((ci_results / scene / "sims").glob("*.h5"))
    with pytest.raises(ValueError, match="different sims"):
        crosscheck.compare(scene, {"lammps": files, "yade": files[:-1]}, 0.05)
    table = crosscheck.compare(scene, {"lammps": files, "yade": files}, 0.05)
    judged = table[table["pass"].notna()]
    assert judged["pass"].all() and (judged["rel_diff"] == 0).all()      # an engine agrees with itself
    for _, row in table[table["pass"].isna()].iterrows():
        assert "not compared" in row["note"]


def test_the_engines_difference_stands_beside_the_dem_chaos(ci_results):
    """The configured engine reruns every cross-checked row from packings perturbed by 1e-6 radii: the
    same sims and layout, a recorded perturbation, trajectories that differ, and a chaos column per metric
    (the perturbation's size: tests/generators/test_engine.py; frame 0 comes after a run-up, where it grew)."""
    table = pd.read_csv(ci_results / "crosscheck.csv")
    for scene in scenes.names():
        configured = config.load({"scale": "ci"})[scene]["engine"]
        rows = table[(table["scene"] == scene) & table["pass"].notna()]
        assert (rows["chaos_engine"] == configured).all() and (rows["chaos_rel_diff"] >= 0).all()
        ids = sorted(p.stem for p in (ci_results / scene / "sims").glob("*.h5"))
        assert sorted(p.stem for p in (ci_results / "crosscheck" / scene / "chaos" / "sims").glob("*.h5")) == ids
        base = h5md.read(ci_results / scene / "sims" / f"{ids[0]}.h5")
        rerun = h5md.read(ci_results / "crosscheck" / scene / "chaos" / "sims" / f"{ids[0]}.h5")
        assert rerun.parameters["engine"] == configured and rerun.parameters["perturbation"] == 1e-6
        assert rerun.position.shape == base.position.shape
        np.testing.assert_array_equal(rerun.kinematic, base.kinematic)
        assert not np.array_equal(rerun.position[:, ~base.kinematic], base.position[:, ~base.kinematic])
