"""Run time against error: contender settings, the Pareto front and the headline ratios."""

import numpy as np
import pandas as pd
import pytest

from evaluation import performance


def contenders():
    return pd.DataFrame([
        {"contender": "reference", "kind": "dem", "stable": True, "seconds_per_rollout": 10.0, "mse": 0.0,
         "seconds_per_frame": 1.0, "seconds_per_dem_step": 0.001},
        {"contender": "dt_x4", "kind": "dem", "stable": True, "seconds_per_rollout": 2.5, "mse": 0.5,
         "seconds_per_frame": 0.25, "seconds_per_dem_step": 0.001},
        {"contender": "soft", "kind": "dem", "stable": True, "seconds_per_rollout": 4.0, "mse": 3.0,
         "seconds_per_frame": 0.4, "seconds_per_dem_step": 0.001},          # slower and worse than dt_x4
        {"contender": "graphdem", "kind": "surrogate", "stable": True, "seconds_per_rollout": 0.5, "mse": 1.0,
         "seconds_per_frame": 0.05},
        {"contender": "blown", "kind": "dem", "stable": False, "seconds_per_rollout": float("nan"),
         "mse": float("nan")},
        {"contender": "untrained", "kind": "surrogate", "stable": True, "seconds_per_rollout": 0.1,
         "mse": float("nan"), "seconds_per_frame": 0.01},
    ])


def test_pareto_front_keeps_only_undominated_scored_contenders():
    front = performance.pareto_front(contenders())
    assert list(front) == [True, True, False, True, False, False]


def test_report_gives_speedups_and_break_even_substeps():
    table = performance.report(contenders(), main="graphdem", reference="reference", settling_seconds=42.0)
    main = table[table["main"]].iloc[0]
    assert main["speedup_vs_reference"] == pytest.approx(20.0)
    # the fastest DEM at least as accurate as the surrogate (MSE <= 1.0) is dt_x4, 2.5 s
    assert main["matched_dem"] == "dt_x4" and main["speedup_vs_matched_dem"] == pytest.approx(5.0)
    # 0.05 s per frame against 1 ms per DEM step: the DEM must take more than 50 steps per frame to be slower
    assert main["break_even_substeps"] == pytest.approx(50.0)
    settling = table[table["contender"] == "dem_settling"].iloc[0]
    assert settling["wall_seconds_per_run"] == 42.0 and pd.isna(settling["seconds_per_rollout"])


def test_report_needs_the_reference():
    with pytest.raises(ValueError, match="DEM reference contender 'exact' is missing or blew up"):
        performance.report(contenders(), main="graphdem", reference="exact", settling_seconds=None)


def test_dem_contender_settings_scale_the_step_and_the_stiffness():
    row = {"id": "s", "dt_safety": 0.01, "dt": None, "young": 1e9, "engine": "lammps"}
    assert performance.dem_row(row, {"dt_factor": 4}) == {**row, "dt_safety": 0.04}
    assert performance.dem_row(row, {"dt_safety": 0.5}) == {**row, "dt_safety": 0.5}
    assert performance.dem_row(row, {"stiffness_factor": 0.01}) == {**row, "young": pytest.approx(1e7)}
    assert performance.dem_row(row, {"cores": 2, "dt_safety": 0.1}) == {**row, "dt_safety": 0.1}  # cores: not physics
    assert performance.dem_row(row, {"engine": "yade", "dt_safety": 0.5}) == {**row, "dt_safety": 0.5, "engine": "yade"}
    allowed = "dt_safety, dt_factor, stiffness_factor, cores, engine"
    with pytest.raises(ValueError, match=rf"unknown keys \['dt'\]; allowed: {allowed}"):
        performance.dem_row(row, {"dt": 1e-4})
    with pytest.raises(ValueError, match="not both"):
        performance.dem_row(row, {"dt_factor": 2, "dt_safety": 0.1})
    with pytest.raises(ValueError, match="must not fix an explicit dt"):
        performance.dem_row({**row, "dt": 1e-5}, {"dt_factor": 2})


def test_cores_are_mpi_ranks_in_lammps_and_threads_in_yade():
    assert performance.execution({"cores": 2}, "lammps") == (2, 1)
    assert performance.execution({"cores": 2}, "yade") == (1, 2)
    assert performance.execution({}, "yade") == (1, 1)


def test_a_dem_contender_in_another_engine_is_checked_when_the_config_is_read():
    from generators import config
    from generators.errors import ConfigError
    cfg = config.load({"scale": "ci", "slide": {"performance": {"dem": {"yade_half": {"engine": "yade",
                                                                                      "dt_safety": 0.5}}}}})
    assert cfg["slide"]["performance"]["dem"]["yade_half"] == {"engine": "yade", "dt_safety": 0.5}
    with pytest.raises(ConfigError, match=r"'slide.performance.dem.x.engine' = 'abaqus'.*\['lammps', 'yade'\]"):
        config.load({"scale": "ci", "slide": {"performance": {"dem": {"x": {"engine": "abaqus"}}}}})


def test_the_match_must_be_as_accurate_on_every_scene_metric():
    table = contenders()
    table["acc_Max Ht"] = [100.0, 90.0, 99.0, 95.0, float("nan"), float("nan")]
    out = performance.report(table, main="graphdem", reference="reference", settling_seconds=None)
    main = out[out["main"]].iloc[0]
    # dt_x4 has the lower MSE but a worse Max Ht (90 < 95): the match on every measure is the reference
    assert main["matched_dem_by_mse"] == "dt_x4" and main["speedup_vs_matched_dem_by_mse"] == pytest.approx(5.0)
    assert main["matched_dem"] == "reference" and main["speedup_vs_matched_dem"] == pytest.approx(20.0)
    # soft is as good on Max Ht (99) but not on the MSE (3.0 > 1.0): never a match
    assert "soft" not in (main["matched_dem"], main["matched_dem_by_mse"])


def test_break_even_against_the_fastest_dem_step():
    table = contenders()
    table.loc[table["contender"] == "soft", "seconds_per_dem_step"] = 0.0005       # e.g. on 2 cores
    out = performance.report(table, main="graphdem", reference="reference", settling_seconds=None)
    main = out[out["main"]].iloc[0]
    assert main["break_even_substeps"] == pytest.approx(50.0)                    # against the reference's step
    assert main["break_even_substeps_fastest"] == pytest.approx(100.0)           # against the cheapest step


def test_speedup_grows_linearly_with_the_dem_substeps():
    table = performance.report(contenders(), main="graphdem", reference="reference", settling_seconds=None)
    curve = performance.speedup_curve(table, "graphdem", np.array([10.0, 100.0]))
    ref = curve[curve["contender"] == "reference"].set_index("substeps_per_frame")["speedup"]
    # 1 ms per DEM step against 50 ms per surrogate frame: 10 sub-steps 0.2x, 100 sub-steps 2x
    assert ref[10.0] == pytest.approx(0.2) and ref[100.0] == pytest.approx(2.0)
    assert "blown" not in set(curve["contender"])


def test_operation_count_matches_the_article_size_model_by_hand():
    model = {"latent": 128, "hidden": 128, "mlp_layers": 3, "history": 6, "embed": 16, "message_passing": 10}
    nodes, edges = 700, 700 * 20
    plain = performance.gflop_per_step(model, 2, 0, nodes, edges, split=False)
    # per edge and updater: 384x128 + 128x128 + 128x128 multiply-adds, per node 256x128 + 2 x 128x128
    updater = edges * (384 + 128 + 128) * 128 + nodes * (256 + 128 + 128) * 128
    constructors = nodes * ((5 * 2 + 16 + 4) * 128 + 2 * 128 * 128) + edges * (3 * 128 + 2 * 128 * 128)
    generator = nodes * (2 * 128 * 128 + 128 * 2)
    assert plain == pytest.approx(2 * (10 * updater + constructors + generator) / 1e9)
    split = performance.gflop_per_step(model, 2, 0, nodes, edges, split=True)
    assert split == pytest.approx(plain - 2 * 10 * (edges * 256 * 128 - 2 * nodes * 128 * 128) / 1e9)


@pytest.mark.engine
def test_a_batched_surrogate_contender_scores_as_the_unbatched_one(tiny_dataset, tmp_path):
    import json

    import torch

    from surrogate import checkpoint, runtime
    from surrogate.simulator import LearnedSimulator
    stats = json.loads(tiny_dataset["stats_json"])
    torch.manual_seed(0)
    simulator = LearnedSimulator(stats, tiny_dataset["model"])
    path = tmp_path / "best.pt"
    checkpoint.save(path, {"model": simulator.state_dict(), "json": {"stats": stats, "model": tiny_dataset["model"]}})
    table = tiny_dataset["split_table"]
    truths = list(table.loc[table["split"] != "train", "path"])                   # 2 sims: valid and test
    base = runtime.Runtime(split_edge_mlp=True, skip_kinematic_pairs=True, prune_isolated=True, precision="float32",
                           sleep_speed=None, keep_in_domain=True, compile=False)
    alone = performance.surrogate_contender("alone", {}, path, base, truths, repeats=1, threads=1)
    for batch in (2, 3):             # 3: more than the sims, so they are repeated to fill the batch
        together = performance.surrogate_contender("together", {"batch": batch}, path, base, truths, repeats=1,
                                                   threads=1)
        assert alone["batch"] == 1 and together["batch"] == batch and together["sims"] == alone["sims"] == 2
        assert together["mse"] == pytest.approx(alone["mse"], rel=1e-5)
        assert together["edges_per_step"] == pytest.approx(alone["edges_per_step"])
        assert together["gflop_per_frame"] == pytest.approx(alone["gflop_per_frame"])
        assert 0 < together["seconds_per_rollout"] < float("inf")
    per_sim = json.loads(alone["per_sim"])            # each sim's own time per frame: they average to the row's
    assert len(per_sim) == 2 and all(s["moving"] <= s["particles"] for s in per_sim.values())
    assert np.mean([s["seconds_per_frame"] for s in per_sim.values()]) == pytest.approx(alone["seconds_per_frame"])
    with pytest.raises(ValueError, match="batch = 0"):
        performance.timed_rollouts(simulator, [], base, False, 1, batch=0)
