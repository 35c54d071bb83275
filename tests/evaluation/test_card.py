"""The benchmark card on small hand-made tables: the numbers by hand (diameters, mean and spread over seeds,
first and last frame, core- and GPU-hours), a blow-up that stays NaN, and the card's files from the command line."""

import json
import math

import pandas as pd
import pytest

from evaluation import card
from evaluation.evaluate import BASELINE, MODEL, MSE, SECONDS
from graphdem import cli

DIAMETER_STATS = {"property_stats": {"radius": {"mean": 2.0, "std": 0.1, "log": False}}}     # d = 4 m
ARTICLE = {"history": 2, "split": "test", "rollout_mse": {"graphdem": 36.0, "gns": 49.0}}
CPU = card.Hardware("cpu", "Some CPU, 2 logical CPUs", 1, 1)


def metrics(mse: float, baseline: float = 100.0, blown: int = 0, seconds: float = 0.008) -> pd.DataFrame:
    """A seed's metrics.csv: rollout MSE of both methods under K = 2 and 6 (2 sims), and Graph-DEM's timing."""
    rows = []
    for k in (2, 6):
        rows += [{"method": MODEL, "metric": MSE, "sim": "all", "history": k, "mse": mse * k / 2,
                  "mean_prediction": mse * k / 2, "n_sims": 2, "n_blown_up": blown, "split": "valid",
                  "split_note": "the source has no test split"},
                 {"method": MODEL, "metric": MSE, "sim": "s0", "history": k, "mse": 1.0, "mean_prediction": 1.0,
                  "n_sims": 1, "n_blown_up": 0, "split": "valid", "split_note": "the source has no test split"},
                 {"method": BASELINE, "metric": MSE, "sim": "all", "history": k, "mse": baseline,
                  "mean_prediction": baseline, "n_sims": 2, "n_blown_up": 0, "split": "valid",
                  "split_note": "the source has no test split"},
                 {"method": MODEL, "metric": SECONDS, "sim": "all", "history": k, "mse": math.nan,
                  "mean_prediction": seconds, "n_sims": 2, "n_blown_up": math.nan, "split": "valid",
                  "split_note": "the source has no test split"}]
    return pd.DataFrame(rows)


def steps(first: float, last: float, nan_sim: bool = False) -> pd.DataFrame:
    """A seed's per-step table: per sim (s0, s1) the MSE at each of 3 predicted frames (K = 2) or 2 (K = 6); the
    mean over sims of the first frame is ``first``, of the last ``last``; a blown-up s1 has NaN from frame 2 on."""
    rows = []
    for method in (MODEL, BASELINE):
        for k, n in ((2, 3), (6, 2)):
            for sim, shift in (("s0", -1.0), ("s1", 1.0)):
                for tau in range(1, n + 1):
                    value = first + shift if tau == 1 else last + shift if tau == n else 7.0
                    if nan_sim and sim == "s1" and tau >= 2 and method == MODEL:
                        value = math.nan
                    rows.append({"method": method, "metric": MSE, "sim": sim, "history": k, "tau": tau,
                                 "prediction": value})
            for tau in range(1, n + 1):       # the mean rows (sim = all) are not what the card reads
                rows.append({"method": method, "metric": MSE, "sim": "all", "history": 2, "tau": tau,
                             "prediction": -1.0})
    return pd.DataFrame(rows)


def history(seconds: list[float], hardware: card.Hardware | None = CPU) -> pd.DataFrame:
    table = pd.DataFrame({"epoch": range(1, len(seconds) + 1), "seconds": seconds})
    if hardware is not None:
        table = table.assign(threads=hardware.threads, processes=hardware.processes, device=hardware.device,
                             device_name=hardware.device_name)
    return table


def three_seeds(nan_seed: bool = False):
    out = {}
    for seed, mse in ((0, 16.0), (1, 25.0), (2, 36.0)):
        blown = nan_seed and seed == 1
        m = metrics(math.nan if blown else mse, blown=int(blown))
        out[seed] = (m, steps(2.0 + seed, 20.0 + seed, nan_sim=blown), card.training(history([1800.0, 3600.0])))
    return out


def row(table: pd.DataFrame, quantity: str, method: str = MODEL, k=2, source: str = card.MEASURED) -> pd.Series:
    here = table[(table["quantity"] == quantity) & (table["method"] == method) & (table["source"] == source)
                 & (table["history"].astype(str) == str(k))]
    assert len(here) == 1, here
    return here.iloc[0]


def test_mean_diameter_is_twice_the_moving_particles_mean_radius_and_refuses_what_it_cannot_use():
    assert card.mean_diameter(DIAMETER_STATS) == 4.0
    with pytest.raises(ValueError, match="no property_stats.radius"):
        card.mean_diameter({"property_stats": {}})
    with pytest.raises(ValueError, match=r"ln\(radius\)"):
        card.mean_diameter({"property_stats": {"radius": {"mean": 0.5, "log": True}}})


def test_the_error_in_diameters_is_the_root_of_the_mse_over_the_mean_diameter():
    table, _, _ = card.card(three_seeds(), DIAMETER_STATS, ARTICLE, "slide_samer")
    r = row(table, "rmse_diameters")
    assert r["values"] == "0:1 1:1.25 2:1.5"              # sqrt(16, 25, 36) / 4 per seed, then over the seeds
    assert (r["mean"], r["std"], r["min"], r["max"]) == pytest.approx((1.25, 0.25, 1.0, 1.5))
    assert r["unit"] == "diameters"
    assert row(table, "rmse_diameters", "graphdem", 2, card.ARTICLE)["mean"] == pytest.approx(6.0 / 4.0)
    assert row(table, "rmse_diameters", "gns", 2, card.ARTICLE)["mean"] == pytest.approx(7.0 / 4.0)


def test_mean_std_range_over_seeds_and_each_protocol():
    table, split, note = card.card(three_seeds(), DIAMETER_STATS, ARTICLE, "slide_samer")
    assert (split, note) == ("valid", "the source has no test split")
    r = row(table, "rollout_mse")
    assert (r["mean"], r["std"], r["min"], r["max"], r["n_seeds"], r["n_sims"]) == (
        pytest.approx(25 + 2 / 3), pytest.approx(math.sqrt(((16 - 77 / 3) ** 2 + (25 - 77 / 3) ** 2
                                                             + (36 - 77 / 3) ** 2) / 2)), 16.0, 36.0, 3, 2)
    assert row(table, "rollout_mse", k=6)["mean"] == pytest.approx(3 * (25 + 2 / 3))    # K = 6 is its own row
    assert r["n_predicted"] == 3 and row(table, "rollout_mse", k=6)["n_predicted"] == 2
    baseline = row(table, "rollout_mse", BASELINE)
    assert baseline["mean"] == 100.0 and baseline["std"] == 0.0          # constant velocity does not depend on it
    assert row(table, "rollout_ms_per_frame")["mean"] == pytest.approx(8.0)
    assert not ((table["quantity"] == "rollout_ms_per_frame") & (table["method"] == BASELINE)).any()
    article = row(table, "rollout_mse", "gns", 2, card.ARTICLE)
    assert article["mean"] == 49.0 and article["split"] == "test" and article["n_seeds"] == card.NOT_APPLICABLE


def test_first_and_last_frame_are_means_over_sims_per_seed_then_over_seeds():
    table, _, _ = card.card(three_seeds(), DIAMETER_STATS, ARTICLE, "slide_samer")
    first, last = row(table, "mse_first_frame"), row(table, "mse_last_frame")
    assert first["values"] == "0:2 1:3 2:4" and first["mean"] == pytest.approx(3.0)
    assert last["values"] == "0:20 1:21 2:22" and last["mean"] == pytest.approx(21.0)
    assert row(table, "mse_last_frame", k=6)["mean"] == pytest.approx(21.0)      # K = 6: its second frame is last


def test_a_blow_up_stays_nan_over_the_seeds_and_is_counted_over_all_of_them():
    table, _, _ = card.card(three_seeds(nan_seed=True), DIAMETER_STATS, ARTICLE, "slide_samer")
    for quantity in ("rollout_mse", "rmse_diameters", "mse_last_frame"):
        r = row(table, quantity)
        assert math.isnan(r["mean"]) and math.isnan(r["std"]) and math.isnan(r["max"]), quantity
        assert "1:nan" in r["values"] and r["n_seeds"] == 3
    assert row(table, "mse_first_frame")["mean"] == pytest.approx(3.0)      # before the blow-up it is defined
    blown = row(table, "blown_up")
    assert blown["total"] == 1.0 and blown["values"] == "0:0 1:1 2:0"
    text = card.markdown(table, "slide_samer", "valid", "", 4.0, {s: t for s, (_, _, t) in three_seeds().items()},
                         "auto")
    assert "| blown up, over all seeds (rollouts) | 2 (3 predicted) | 1 of 6 | 0 of 6 |  |  |" in text
    assert "| rollout MSE (m^2) | 2 (3 predicted) | NaN (seeds 1) | 100 ± 0 [100 .. 100] | 36 | 49 |" in text


def test_core_hours_are_each_epochs_seconds_times_its_threads_and_processes():
    two = card.Hardware("cpu", "Some CPU", 2, 2)
    train = card.training(history([1800.0, 5400.0], two))
    assert (train.seconds, train.hours, train.unit, train.recorded) == (5400.0, 6.0, card.CORE_HOURS, True)
    # a job resumed on other hardware: each epoch at its own
    mixed = history([1800.0, 5400.0], two)
    mixed.loc[1, ["threads", "processes"]] = [1, 1]
    assert card.training(mixed).hours == pytest.approx(0.5 * 4 + 1.0 * 1)


def test_gpu_hours_count_gpus_not_threads_and_a_mix_with_the_cpu_is_refused():
    gpu = card.Hardware("cuda:0", "Some GPU", 16, 2)
    train = card.training(history([3600.0, 7200.0], gpu))
    assert (train.hours, train.unit) == (4.0, card.GPU_HOURS) and "2 x GPU (Some GPU)" in train.hardware[0].describe()
    mixed = history([3600.0, 7200.0], gpu)
    mixed.loc[1, "device"] = "cpu"
    with pytest.raises(ValueError, match="some epochs ran on a GPU and some on the CPU"):
        card.training(mixed)


def test_a_history_without_hardware_columns_takes_the_fallback_or_is_refused():
    old = history([600.0, 1200.0], hardware=None)
    with pytest.raises(ValueError, match="does not record where it ran"):
        card.training(old)
    train = card.training(old, card.Hardware("cpu", "Some CPU", 3, 1))
    assert train.hours == pytest.approx(1200 * 3 / 3600) and not train.recorded
    with pytest.raises(ValueError, match="cumulative"):
        card.training(history([600.0, 300.0]))


def test_seeds_that_differ_in_what_they_scored_or_how_they_trained_are_refused():
    seeds = three_seeds()
    m, s, t = seeds[2]
    seeds[2] = (m[m["history"] == 2], s, t)
    with pytest.raises(ValueError, match=r"seeds \[2\] have no value"):
        card.card(seeds, DIAMETER_STATS, ARTICLE, "slide_samer")
    seeds = three_seeds()
    m, s, _ = seeds[1]
    seeds[1] = (m, s, card.training(history([3600.0], card.Hardware("cuda:0", "Some GPU", 1, 1))))
    with pytest.raises(ValueError, match="trained on different hardware"):
        card.card(seeds, DIAMETER_STATS, ARTICLE, "slide_samer")
    seeds = three_seeds()
    m, s, t = seeds[1]
    seeds[1] = (m.assign(split="test"), s, t)
    with pytest.raises(ValueError, match="different splits"):
        card.card(seeds, DIAMETER_STATS, ARTICLE, "slide_samer")


def test_the_command_writes_the_csv_and_the_markdown(tmp_path):
    args = {"--metrics": [], "--steps": [], "--histories": []}
    for seed, (m, s, _) in three_seeds().items():
        for flag, table, name in (("--metrics", m, "metrics"), ("--steps", s, "steps"),
                                  ("--histories", history([1800.0, 3600.0]), "history")):
            path = tmp_path / f"{name}_{seed}.csv"
            table.to_csv(path, index=False)
            args[flag].append(str(path))
    (tmp_path / "stats.json").write_text(json.dumps(DIAMETER_STATS))
    argv = ["card", "--benchmark", "slide_small", "--seeds", "0", "1", "2", "--stats", str(tmp_path / "stats.json"),
            "--article-json", json.dumps(ARTICLE), "--device", "cpu", "--out", str(tmp_path / "card.csv"),
            "--markdown", str(tmp_path / "card.md")]
    for flag, paths in args.items():
        argv += [flag, *paths]
    assert cli.main(argv) == 0
    table = pd.read_csv(tmp_path / "card.csv")
    assert list(table.columns) == list(card.COLUMNS)
    assert set(table["quantity"]) == set(card.QUANTITIES)
    cost = table[table["quantity"] == "train_cost"].iloc[0]
    assert cost["unit"] == "core-hours" and cost["mean"] == pytest.approx(1.0) and pd.isna(cost["history"])
    assert set(table.loc[table["source"] == "measured", "split"].dropna()) == {"valid"}      # training: no split
    text = (tmp_path / "card.md").read_text()
    assert "Scored on the **valid** split (2 sims per seed): the source has no test split." in text
    assert "Mean particle diameter d = 4 m" in text and "CPU (Some CPU, 2 logical CPUs)" in text
    assert "| training cost per model (core-hours) | all | 1 ± 0 [1 .. 1] |" in text
    assert "ours are on valid, not test" in text
    with pytest.raises(SystemExit, match="both --ensemble-metrics and --ensemble-steps"):
        cli.main([*argv, "--ensemble-metrics", args["--metrics"][0]])


def test_the_seed_ensemble_is_one_evaluation_costed_as_all_its_models():
    """The ensemble's rows: its own evaluation (no spread), its models' training summed, its constant velocity rows
    left to the seeds; a split other than the seeds' is refused."""
    seeds = three_seeds()
    ensemble = (metrics(9.0, baseline=555.0, seconds=0.024), steps(1.0, 10.0))
    table, _, _ = card.card(seeds, DIAMETER_STATS, ARTICLE, "slide_samer", ensemble)
    mse = row(table, "rollout_mse", card.ENSEMBLE)
    assert mse["mean"] == 9.0 and mse["n_seeds"] == 3 and mse["values"] == "0+1+2" and mse["std"] == card.NOT_APPLICABLE
    assert row(table, "rollout_mse", card.ENSEMBLE, k=6)["mean"] == 27.0
    assert row(table, "rmse_diameters", card.ENSEMBLE)["mean"] == pytest.approx(3.0 / 4.0)
    assert row(table, "mse_first_frame", card.ENSEMBLE)["mean"] == 1.0
    assert row(table, "mse_last_frame", card.ENSEMBLE)["mean"] == 10.0
    assert row(table, "rollout_ms_per_frame", card.ENSEMBLE)["mean"] == pytest.approx(24.0)
    assert row(table, "blown_up", card.ENSEMBLE)["total"] == 0
    assert row(table, "train_seconds", card.ENSEMBLE, k="")["mean"] == 3 * 3600.0
    assert row(table, "train_cost", card.ENSEMBLE, k="")["mean"] == pytest.approx(3.0)          # 3 x 1 core-hour
    assert row(table, "rollout_mse", BASELINE)["mean"] == 100.0             # the seeds' constant velocity, not 555
    assert not ((table["method"] == card.ENSEMBLE) & (table["quantity"] == "rollout_mse")
                & (table["mean"] == 555.0)).any()
    text = card.markdown(table, "slide_samer", "valid", "", 4.0, {s: t for s, (_, _, t) in seeds.items()}, "cpu")
    assert "| seed ensemble |" in text and "9 (3 models)" in text and "3 (3 models in all)" in text
    other = metrics(9.0).assign(split="test")
    with pytest.raises(ValueError, match="seed ensemble was scored on the 'test' split"):
        card.card(seeds, DIAMETER_STATS, ARTICLE, "slide_samer", (other, steps(1.0, 10.0)))
    with pytest.raises(ValueError, match="at least two models"):
        card.card({0: seeds[0]}, DIAMETER_STATS, ARTICLE, "slide_samer", ensemble)


def test_the_command_refuses_a_file_count_that_does_not_match_the_seeds(tmp_path):
    with pytest.raises(SystemExit, match="give one file per seed"):
        cli.main(["card", "--benchmark", "slide_small", "--seeds", "0", "1", "--metrics", "a.csv",
                  "--steps", "a.csv", "b.csv", "--histories", "a.csv", "b.csv", "--stats", "s.json",
                  "--article-json", "{}", "--out", str(tmp_path / "c.csv"), "--markdown", str(tmp_path / "c.md")])


def test_the_command_costs_an_old_history_at_the_threads_it_is_given(tmp_path):
    """A history.csv without the hardware columns: --train-threads on --device (here cpu), said on the card."""
    m, s, _ = three_seeds()[0]
    m.to_csv(tmp_path / "m.csv", index=False)
    s.to_csv(tmp_path / "s.csv", index=False)
    history([1800.0, 3600.0], hardware=None).to_csv(tmp_path / "h.csv", index=False)
    (tmp_path / "stats.json").write_text(json.dumps(DIAMETER_STATS))
    argv = ["card", "--benchmark", "slide_samer", "--seeds", "0", "--metrics", str(tmp_path / "m.csv"),
            "--steps", str(tmp_path / "s.csv"), "--histories", str(tmp_path / "h.csv"),
            "--stats", str(tmp_path / "stats.json"), "--article-json", json.dumps(ARTICLE), "--device", "cpu",
            "--out", str(tmp_path / "card.csv"), "--markdown", str(tmp_path / "card.md")]
    assert cli.main(argv) == 1                          # without --train-threads: refused, naming the file
    assert cli.main([*argv, "--train-threads", "2"]) == 0
    cost = pd.read_csv(tmp_path / "card.csv").query("quantity == 'train_cost'").iloc[0]
    assert cost["mean"] == pytest.approx(2.0) and cost["std"] != cost["std"]           # one seed: no spread
    text = (tmp_path / "card.md").read_text()
    assert "not recorded in history.csv, assumed from the workflow's settings" in text and "(1 seed)" in text
