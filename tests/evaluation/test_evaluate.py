"""`graphdem evaluate --checkpoint CKPT --data DIR --history K --out CSV` on a tiny real dataset."""

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from generators import h5md
from graphdem import cli
from surrogate import train

pytestmark = pytest.mark.engine


@pytest.fixture(scope="module")
def trained(tiny_dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp("model")
    train.train(tiny_dataset["stats_path"], tiny_dataset["splits"], tiny_dataset["model"], tiny_dataset["train"],
                out, progress=False)
    return out / "best.pt"


def test_evaluate_cli_writes_mse_per_sim_and_scene_metrics(tiny_dataset, trained, tmp_path, capsys):
    sims = tiny_dataset["root"] / "sims"
    out = tmp_path / "metrics.csv"
    code = cli.main(["evaluate", "--checkpoint", str(trained), "--data", str(sims), "--history", "4",
                     "--out", str(out), "--per-step", str(tmp_path / "steps.csv"), "--plots", str(tmp_path / "plots"),
                     "--no-progress"])
    assert code == 0
    printed = capsys.readouterr().out
    table = pd.read_csv(out)
    mse = table[(table["metric"] == "rollout MSE") & (table["method"] == "graphdem")]
    per_sim = mse[mse["sim"] != "all"]
    assert sorted(per_sim["sim"]) == [f"slide_{i:04d}" for i in range(4)]     # every sim of the folder
    overall = mse[mse["sim"] == "all"]["mse"].iloc[0]
    assert overall == pytest.approx(per_sim["mse"].mean()) and np.isfinite(overall)
    assert "rollout MSE of slide_0000" in printed
    assert f"rollout MSE {overall:.4g} m^2" in " ".join(printed.split()) and "MSE MSE" not in printed
    metrics = set(table.loc[table["sim"] == "all", "metric"])
    assert {"Slide Num", "Max Ht", "Mean Ht", "Tongue Dis", "Dis", "Dis mean", "seconds per frame"} <= metrics
    assert set(table["method"]) == {"graphdem", "constant_velocity"}
    assert table["checkpoint_sha"].nunique() == 1 and table["code_version"].str.startswith("0.1.0").all()
    # every row names its unit; the rollout MSE's one figure is its mse (no copy in mean_prediction)
    units = table.drop_duplicates("metric").set_index("metric")["unit"]
    assert (units["rollout MSE"], units["Max Ht"], units["Slide Num"], units["seconds per frame"],
            units["Kinetic energy"], units["Max overlap"]) == ("m^2", "m", "particles", "s", "J", "radii")
    assert table["unit"].notna().all() and table.loc[table["metric"] == "rollout MSE", "mean_prediction"].isna().all()
    # the config lies beside the table once, under the digest every row names (the checkpoint's config digest)
    from evaluation import config_sidecar, tables
    from surrogate import checkpoint, ensemble
    assert "config" not in table.columns and "config" not in pd.read_csv(tmp_path / "steps.csv").columns
    sha = tables.read_csv(out)["config_sha"].unique()
    meta = checkpoint.simulator_from(trained, "cpu")[1]
    assert list(sha) == [ensemble.config_digest([meta])]
    assert config_sidecar.read(out, sha[0]) == config_sidecar.config_of([meta])
    steps = pd.read_csv(tmp_path / "steps.csv")
    assert set(steps["tau"]) == set(range(1, 10 - 4 + 1))
    assert (tmp_path / "plots" / "rollout.gif").read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    assert (tmp_path / "plots" / "metrics_over_frames.png").stat().st_size > 10_000


def test_scene_metric_truth_is_the_same_for_both_methods(tiny_dataset, trained, tmp_path):
    cli.main(["evaluate", "--checkpoint", str(trained), "--data", str(tiny_dataset["root"] / "sims"),
              "--history", "4", "--out", str(tmp_path / "m.csv"), "--per-step", str(tmp_path / "s.csv"),
              "--no-progress"])
    steps = pd.read_csv(tmp_path / "s.csv")
    part = steps[(steps["metric"] == "Slide Num") & (steps["sim"] != "all")]
    a = part[part["method"] == "graphdem"]["truth"].to_numpy()
    b = part[part["method"] == "constant_velocity"]["truth"].to_numpy()
    np.testing.assert_array_equal(a, b)


def test_a_history_shorter_than_the_models_is_refused_with_the_allowed_values(tiny_dataset, trained, tmp_path,
                                                                               capsys):
    code = cli.main(["evaluate", "--checkpoint", str(trained), "--data", str(tiny_dataset["root"] / "sims"),
                     "--history", "3", "--out", str(tmp_path / "m.csv")])
    assert code == 1
    assert "reads a history of K = 4 frames; --history 3 gives fewer (allowed: 4 or more)" in capsys.readouterr().err
    assert not (tmp_path / "m.csv").exists()


def test_a_longer_protocol_scores_the_frames_after_it(tiny_dataset, trained, tmp_path, capsys):
    """--history 6 on a K = 4 model: 6 frames given, the rest predicted and scored (both methods)."""
    data = str(tiny_dataset["root"] / "sims")
    assert cli.main(["evaluate", "--checkpoint", str(trained), "--data", data, "--history", "6",
                     "--out", str(tmp_path / "m.csv"), "--per-step", str(tmp_path / "s.csv")]) == 0
    steps = pd.read_csv(tmp_path / "s.csv")
    mse = steps[(steps["metric"] == "rollout MSE") & (steps["sim"] != "all")]
    assert mse["frame"].min() == 6 and set(mse["history"]) == {6}
    n_frames = h5md.read(next(iter(sorted((tiny_dataset["root"] / "sims").glob("*.h5"))))).position.shape[0]
    assert (mse.groupby(["method", "sim"])["frame"].count() == n_frames - 6).all()


def test_a_rollout_that_blows_up_midway_counts_and_is_named():
    from evaluation.evaluate import MSE, mean_per_step, summarise
    steps = pd.DataFrame({"scene": "slide", "method": "graphdem", "metric": MSE, "sim": ["a"] * 3 + ["b"] * 3,
                          "tau": [1, 2, 3] * 2, "frame": [6, 7, 8] * 2, "time": [1.0, 1.2, 1.4] * 2,
                          "truth": np.nan, "prediction": [0.1, 0.2, 0.3, 0.1, np.nan, np.nan]})
    table = summarise(steps)
    overall = table[table["sim"] == "all"].iloc[0]
    assert np.isnan(overall["mse"]) and overall["n_blown_up"] == 1 and overall["blown_up_sims"] == "b"
    per_sim = table[table["sim"] != "all"].set_index("sim")["mse"]
    assert per_sim["a"] == pytest.approx(0.2) and np.isnan(per_sim["b"])
    mean = mean_per_step(steps)
    assert mean["prediction"].iloc[0] == pytest.approx(0.1) and mean["prediction"].iloc[1:].isna().all()


def test_the_per_step_table_keeps_each_protocols_mean_rows_apart(tmp_path):
    """Two protocols in one per-step table: the mean over sims of K = 6 is labelled K = 6, not the first K."""
    from evaluation.evaluate import MSE, write
    steps = pd.DataFrame([{"scene": "solidgn", "method": "graphdem", "sim": sim, "metric": MSE, "tau": tau,
                           "frame": k + tau - 1, "time": 0.0, "truth": np.nan, "prediction": float(k * tau),
                           "blown_up": False, "history": k, "split": "valid"}
                          for k in (2, 6) for sim in ("a", "b") for tau in (1, 2)])
    write(pd.DataFrame({"metric": [MSE]}), steps, tmp_path / "m.csv", tmp_path / "s.csv")
    mean = pd.read_csv(tmp_path / "s.csv").query("sim == 'all'").set_index(["history", "tau"])["prediction"]
    assert mean.to_dict() == {(2, 1): 2.0, (2, 2): 4.0, (6, 1): 6.0, (6, 2): 12.0}


def test_evaluation_split_prefers_test_and_says_when_it_falls_back_to_valid():
    from evaluation.evaluate import evaluation_split
    both = pd.DataFrame({"id": ["a", "b", "c"], "split": ["train", "valid", "test"], "path": ["a", "b", "c"]})
    assert evaluation_split(both, "auto") == ("test", [Path("c")], "")
    no_test = both[both["split"] != "test"]
    split, paths, note = evaluation_split(no_test, "auto")
    assert (split, paths) == ("valid", [Path("b")]) and "no test split" in note
    assert "although a test split exists" in evaluation_split(both, "valid")[2]
    with pytest.raises(ValueError, match=r"no test sims \(it has \['train', 'valid'\]\)"):
        evaluation_split(no_test, "test")


def test_evaluate_on_a_split_table_names_the_split_in_every_row(tiny_dataset, trained, tmp_path, capsys):
    table = tiny_dataset["split_table"]
    no_test = tmp_path / "splits.csv"
    table[table["split"] != "test"].to_csv(no_test, index=False)
    out = tmp_path / "metrics.csv"
    code = cli.main(["evaluate", "--checkpoint", str(trained), "--splits", str(no_test), "--split", "auto",
                     "--history", "4", "--out", str(out), "--per-step", str(tmp_path / "steps.csv"), "--no-progress"])
    assert code == 0
    assert "NOTE: evaluated on the valid split" in capsys.readouterr().out
    for written in (pd.read_csv(out), pd.read_csv(tmp_path / "steps.csv")):
        assert set(written["split"]) == {"valid"} and written["split_note"].str.contains("no test split").all()
    valid_ids = set(table.loc[table["split"] == "valid", "id"])
    scored = pd.read_csv(out)
    assert set(scored.loc[scored["sim"] != "all", "sim"]) == valid_ids


def test_combine_stacks_tables_and_refuses_different_columns(tmp_path):
    from evaluation.evaluate import combine
    pd.DataFrame({"metric": ["rollout MSE"], "history": [2], "mse": [30.0]}).to_csv(tmp_path / "a.csv", index=False)
    pd.DataFrame({"metric": ["rollout MSE"], "history": [6], "mse": [40.0]}).to_csv(tmp_path / "b.csv", index=False)
    stacked = combine([tmp_path / "a.csv", tmp_path / "b.csv"])
    assert stacked["history"].tolist() == [2, 6] and stacked["mse"].tolist() == [30.0, 40.0]
    pd.DataFrame({"metric": ["rollout MSE"], "mse": [40.0]}).to_csv(tmp_path / "c.csv", index=False)
    with pytest.raises(ValueError, match="c.csv: columns"):
        combine([tmp_path / "a.csv", tmp_path / "c.csv"])


def test_every_metric_of_a_blown_up_rollout_is_nan_and_flagged_never_finite_garbage(tiny_dataset):
    """A rollout that goes non-finite, or far outside the box while staying finite, has no Acc and no scene
    metric: NaN, with the sim named in n_blown_up/blown_up_sims; the exact prediction scores 100 %."""
    from evaluation.evaluate import MSE, blown_up_from, score, summarise
    table = tiny_dataset["split_table"]
    path = table.loc[table["split"] == "test", "path"].iloc[0]
    traj = h5md.read(path)
    truth = np.asarray(traj.position, np.float64)
    moving = ~traj.kinematic
    nan, far = truth.copy(), truth.copy()
    nan[7:, moving] = np.nan
    far[8:, moving] *= 1.0e6
    assert blown_up_from(nan, traj, 6) == 7 and blown_up_from(far, traj, 6) == 8
    assert blown_up_from(truth, traj, 6) is None
    steps = pd.concat(score("s", traj, truth, {"exact": truth, "nan": nan, "far": far}, 6), ignore_index=True)
    overall = summarise(steps).query("sim == 'all'").set_index(["method", "metric"])
    scene_metrics = [m for m in overall.loc["exact"].index if m != MSE]
    assert {"Slide Num", "Mean Ht", "Dis"} <= set(scene_metrics)
    for method in ("nan", "far"):
        rows = overall.loc[method]
        assert (rows["n_blown_up"] == 1).all() and (rows["blown_up_sims"] == "s").all()
        assert rows["acc_percent"].isna().all() and rows.loc[scene_metrics, "mean_prediction"].isna().all()
        assert np.isnan(rows.loc[MSE, "mse"])
    exact = overall.loc["exact"]
    assert (exact["n_blown_up"] == 0).all() and exact["acc_percent"].dropna().eq(100.0).all()
    assert exact.loc[MSE, "mse"] == 0.0


def test_the_dem_ensemble_is_scored_as_a_third_method_by_the_same_code(tiny_dataset, trained, tmp_path):
    """An ensemble member identical to its sim scores MSE 0 and Acc 100 % (the code path is the one Graph-DEM's
    goes through); one displaced by a known amount scores exactly that squared displacement; the article-style Acc
    takes only the frames asked for."""
    sims = sorted((tiny_dataset["root"] / "sims").glob("*.h5"))
    ensemble = tmp_path / "ensemble"
    ensemble.mkdir()
    for path in sims:
        (ensemble / path.name).write_bytes(path.read_bytes())
    out = tmp_path / "m.csv"
    assert cli.main(["evaluate", "--checkpoint", str(trained), "--data", *map(str, sims), "--history", "4",
                     "--ensemble", str(ensemble), "--frames", "2", "4", "9", "--out", str(out), "--no-progress"]) == 0
    table = pd.read_csv(out)
    assert set(table["method"]) == {"graphdem", "constant_velocity", "dem_ensemble", "dem_ensemble_mean"}
    member = table[(table["method"] == "dem_ensemble") & (table["sim"] == "all")].set_index("metric")
    assert member.at["rollout MSE", "mse"] == 0.0
    # the tiny slides have no landslide body yet (their scene metrics are undefined); the kinetic energy has a truth
    energy = member.loc["Kinetic energy"]
    assert energy["acc_percent"] == 100.0 and energy["acc_pooled_percent"] == 100.0
    assert member.at["Kinetic energy", "acc_frames"] == "2 4"       # tau 9 lies beyond the 6 predicted frames
    for name in ("Max overlap", "P99 overlap", "Outside box", "Through wall", "Kinetic energy"):
        assert member.at[name, "mean_prediction"] == member.at[name, "mean_truth"]
    model = table[(table["method"] == "graphdem") & (table["sim"] == "all")].set_index("metric")
    assert model.at["Max overlap", "mean_truth"] == member.at["Max overlap", "mean_truth"] < 0.1
    # a member displaced by 0.3 m in x on every moving particle from frame 5 on: MSE 0.09 on those frames
    traj = h5md.read(sims[0])
    moved = np.asarray(traj.position, np.float64).copy()
    moved[5:, ~traj.kinematic, 0] += 0.3
    h5md.write(ensemble / sims[0].name, dataclasses.replace(traj, position=moved))
    assert cli.main(["evaluate", "--checkpoint", str(trained), "--data", str(sims[0]), "--history", "4",
                     "--ensemble", str(ensemble), "--out", str(out), "--no-progress"]) == 0
    table = pd.read_csv(out)
    mse = table[(table["method"] == "dem_ensemble") & (table["metric"] == "rollout MSE") & (table["sim"] == "all")]
    # positions are stored in float32: 0.3 m on coordinates of tens of metres keeps about 6 digits
    assert mse["mse"].iloc[0] == pytest.approx(0.09 * (traj.n_frames - 5) / (traj.n_frames - 4), rel=1e-5)


def test_an_ensemble_member_of_other_frames_or_none_at_all_is_refused_by_name(tiny_dataset, trained, tmp_path, capsys):
    sims = sorted((tiny_dataset["root"] / "sims").glob("*.h5"))
    ensemble = tmp_path / "ensemble"
    ensemble.mkdir()
    traj = h5md.read(sims[0])
    short = dataclasses.replace(traj, position=traj.position[:-1], time=traj.time[:-1], step=traj.step[:-1],
                                observables={k: v[:-1] for k, v in traj.observables.items()})
    h5md.write(ensemble / sims[0].name, short)
    args = ["evaluate", "--checkpoint", str(trained), "--data", str(sims[0]), "--history", "4", "--ensemble",
            str(ensemble), "--out", str(tmp_path / "m.csv"), "--no-progress"]
    assert cli.main(args) == 1
    assert f"{ensemble / sims[0].name}: shape" in capsys.readouterr().err
    (ensemble / sims[0].name).unlink()
    assert cli.main(args) == 1
    assert "no DEM ensemble run of this sim" in capsys.readouterr().err
    assert not (tmp_path / "m.csv").exists()


def test_a_model_trained_on_user_data_is_scored_by_the_generic_metrics_only(tiny_dataset, tmp_path):
    """The same weights and sims: with stats.json's user_data (graphdem dataset --user-data) the slide's own metrics
    give way to the generic ones (rollout MSE, plausibility, kinetic energy), with the same rollout MSE and truth."""
    import json

    import torch

    from surrogate import checkpoint
    from surrogate.simulator import LearnedSimulator
    stats = json.loads(tiny_dataset["stats_json"])
    torch.manual_seed(0)
    weights = LearnedSimulator(stats, tiny_dataset["model"]).state_dict()
    test = tiny_dataset["split_table"].query("split == 'test'")["path"].iloc[0]
    tables = {}
    for kind, recorded in (("scene", stats), ("user", {**stats, "user_data": {"folder": "mine", "seed": 0}})):
        checkpoint.save(tmp_path / f"{kind}.pt", {"model": weights, "json": {
            "stats": recorded, "model": tiny_dataset["model"], "train": tiny_dataset["train"]}})
        out = tmp_path / f"{kind}.csv"
        assert cli.main(["evaluate", "--checkpoint", str(tmp_path / f"{kind}.pt"), "--data", str(test), "--history",
                         "4", "--out", str(out), "--no-progress"]) == 0
        tables[kind] = pd.read_csv(out).query("sim == 'all'").set_index(["method", "metric"])
    generic = {"rollout MSE", "Max overlap", "P99 overlap", "Outside box", "Through wall", "Kinetic energy",
               "seconds per frame"}
    assert set(tables["user"].index.get_level_values("metric")) == generic
    assert {"Slide Num", "Tongue Dis", "Dis"} <= set(tables["scene"].index.get_level_values("metric"))
    assert set(tables["user"].index.get_level_values("method")) == {"graphdem", "constant_velocity"}
    for key in [(m, "rollout MSE") for m in ("graphdem", "constant_velocity")]:
        assert np.isfinite(tables["user"].at[key, "mse"])
        assert tables["user"].at[key, "mse"] == pytest.approx(tables["scene"].at[key, "mse"])
    energy = ("graphdem", "Kinetic energy")
    assert tables["user"].at[energy, "mean_truth"] == pytest.approx(tables["scene"].at[energy, "mean_truth"])
