"""The Snakemake workflow on the ci scale: a real run, config errors, and what a change reruns."""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from generators import config, h5md, scenes
from generators.scenes import shear

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")
TARGET = "results/slide/metrics.csv"
# performance.alone false: the ci run's contenders run side by side (their times are not looked at); the
# contenders set to null are left out (each one more of the same kind of job: a DEM step or a runtime switch;
# the compiled rollout alone is tests/surrogate/test_runtime.py's, compiled_batch_8 compiles here)
SMALL = ("slide={n_sims: 3, frames: 8, record_start: 0.5, settle_time: 4.0, performance: {alone: false, "
         "dem: {dt_5pct: null, dt_20pct: null, dt_50pct_2cores: null, stiffness_div10: null, "
         "stiffness_div10_dt_20pct: null}, surrogate: {no_correction: null, compiled: null, kinematic_pairs: null, "
         "float64: null, bfloat16: null, article_size_no_skipping: null, sleep: null}}}")

pytestmark = pytest.mark.engine


def snakemake(workdir, *args, config=(SMALL,)):
    snakefile = str(ROOT / "workflow" / "Snakefile")
    cmd = [SNAKEMAKE, *args, "-s", snakefile, "-d", str(workdir), "--config", "scale=ci", *config]
    return subprocess.run(cmd, capture_output=True, text=True)


def planned(proc) -> dict[str, int]:
    """Job counts per rule from a dry run's 'Job stats' table."""
    assert proc.returncode == 0, proc.stdout + proc.stderr
    text = proc.stdout + proc.stderr
    if "Nothing to be done" in text:
        return {}
    table = text.split("Job stats:")[1].split("total")[0]
    return {m[1]: int(m[2]) for m in re.finditer(r"^(\w+)\s+(\d+)\s*$", table, re.M) if m[1] != "job"}


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    wd = tmp_path_factory.mktemp("wf")
    proc = snakemake(wd, TARGET, "results/slide/performance.csv", "results/slide/stability.csv", "-c2")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return wd


def test_dataset_stage_outputs(workdir):
    res = workdir / "results" / "slide"
    stats = json.loads((res / "dataset" / "stats.json").read_text())
    assert stats["dim"] == 2 and stats["n_types"] == 3 and stats["kinematic_species"] == [0]
    assert stats["connectivity_radius"] == 14.0
    assert (res / "plots" / "dataset_sample.png").stat().st_size > 10_000
    for sim in ("slide_0000", "slide_0001", "slide_0002"):
        traj = h5md.read(res / "sims" / f"{sim}.h5")
        assert traj.n_frames == 8
        assert (res / "logs" / "simulate" / f"{sim}.log").is_file()
        assert (res / "timings" / "simulate" / f"{sim}.tsv").is_file()
        assert (res / "raw" / sim / "in.lammps").is_file() and (res / "raw" / sim / "log.lammps").is_file()
    assert len(list((res / "packings").iterdir())) == 1        # one packing shared by all sims


def test_surrogate_stage_outputs(workdir):
    import pandas as pd
    res = workdir / "results" / "slide"
    history = pd.read_csv(res / "model" / "history.csv")
    assert len(history) == 2 and (res / "model" / "best.pt").is_file() and (res / "model" / "last.pt").is_file()
    test_ids = pd.read_csv(res / "dataset" / "splits.csv").query("split == 'test'")["id"]
    for sim in test_ids:
        rolled = h5md.read(res / "rollouts" / f"{sim}.h5", allow_nonfinite=True)
        assert rolled.parameters["rollout_history"] == 6 and rolled.n_frames == 8
        assert (res / "timings" / "rollout" / f"{sim}.tsv").is_file()
    metrics = pd.read_csv(res / "metrics.csv")
    overall = metrics[metrics["sim"] == "all"]
    assert {"rollout MSE", "Slide Num", "Max Ht", "Mean Ht", "Tongue Dis", "Dis"} <= set(overall["metric"])
    steps = pd.read_csv(res / "metrics_per_step.csv")
    assert set(steps["tau"]) == {1, 2}
    assert (res / "plots" / "rollout.gif").stat().st_size > 10_000
    for stage in ("train", "evaluate"):
        assert (res / "timings" / f"{stage}.tsv").is_file() and (res / "logs" / f"{stage}.log").is_file()


def test_seeds_stage_trains_the_other_seeds_and_reports_the_spread(workdir):
    """seeds=2: one more model (seed 1) beside the main one (seed 0), each scored by the same evaluation."""
    import pandas as pd

    from surrogate import checkpoint
    proc = snakemake(workdir, "results/slide/seeds.csv", "-c2", config=(SMALL, "seeds=2"))
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    res = workdir / "results" / "slide"
    assert checkpoint.load(res / "seeds" / "1" / "model" / "best.pt")["json"]["train"]["seed"] == 1
    table = pd.read_csv(res / "seeds.csv")
    main = pd.read_csv(res / "metrics.csv").query("sim == 'all' and metric == 'rollout MSE'").set_index("method")
    mse = table[(table["metric"] == "rollout MSE") & (table["column"] == "mse")].set_index("method")
    assert (mse["n_seeds"] == 2).all()
    first = float(mse.at["graphdem", "values"].split()[0].split(":")[1])
    assert first == pytest.approx(main.at["graphdem", "mse"], rel=1e-5)     # seed 0 is the main model
    assert mse.at["graphdem", "std"] > 0 and mse.at["graphdem", "min"] < mse.at["graphdem", "max"]
    assert mse.at["constant_velocity", "std"] == 0.0 and mse.at["dem_ensemble", "std"] == 0.0
    assert (res / "seeds" / "1" / "logs" / "train.log").is_file()
    assert (res / "seeds" / "1" / "timings" / "evaluate.tsv").is_file()
    from evaluation import config_sidecar
    seed_metrics = res / "seeds" / "1" / "metrics.csv"       # its declared sidecar names the seed's config
    assert config_sidecar.read(seed_metrics, pd.read_csv(seed_metrics)["config_sha"].iloc[0])["train"]["seed"] == 1


def test_performance_stage_outputs(workdir):
    import pandas as pd
    res = workdir / "results" / "slide"
    table = pd.read_csv(res / "performance.csv").set_index("contender")
    # the reference rerun of the DEM reproduces the data bit for bit (one thread, same inputs)
    assert table.at["reference", "mse"] == 0.0 and table.at["reference", "acc_Max Ht"] == 100.0
    ref = table.loc["reference"]
    assert ref["dt_over_limit"] == pytest.approx(0.01) and ref["cores"] == 1
    # 2 % of the stable limit is twice the data's step: half the sub-steps per frame
    assert table.at["dt_2pct", "dem_steps_per_frame"] == pytest.approx(ref["dem_steps_per_frame"] / 2, abs=1)
    assert table.at["dt_50pct", "dt_over_limit"] == pytest.approx(0.5)
    assert table.at["dt_2pct", "mse"] > 0
    # the same step on 2 MPI ranks: the same contacts, one rank each half of the domain
    assert table.at["dt_10pct_2cores", "ranks"] == 2 and table.at["dt_10pct_2cores", "cores"] == 2
    assert table.at["dt_10pct_2cores", "dem_steps_per_frame"] == table.at["dt_10pct", "dem_steps_per_frame"]
    # start-up and run-up are timed apart from the window; the window is what a rollout is compared with
    assert (table.loc[table["kind"] == "dem", ["startup_seconds", "runup_seconds"]] > 0).all().all()
    assert (table.loc[table["kind"] == "dem", "seconds_per_particle_step"] > 0).all()
    main = table.loc["graphdem"]
    assert main["main"] and main["speedup_vs_reference"] > 0 and main["break_even_substeps"] > 0
    assert main["matched_dem_by_mse"] in table.index and main["seconds_per_particle_step"] > 0
    if main["matched_dem"]:                            # as accurate on the MSE and every scene metric
        matched = table.loc[main["matched_dem"]]
        assert matched["mse"] <= main["mse"] and all(matched[c] >= main[c] for c in table
                                                     if c.startswith("acc_") and pd.notna(main[c]))
    assert table.at["graphdem_2threads", "threads"] == 2
    # the levers change the arithmetic, not the result: batched (and compiled) rollouts score as the plain one
    for lever in ("batch_4", "compiled_batch_8"):
        assert table.at[lever, "mse"] == pytest.approx(main["mse"], rel=1e-4)
    assert table.at["batch_4", "batch"] == 4
    assert (res / "plots" / "speedup_substeps.png").stat().st_size > 10_000
    # the map: per test sim, the reference's sub-steps over the break-even are its speed-up (the DEM's own timing)
    sims = pd.read_csv(res / "performance_map.csv")
    ref_sims = sims[sims["match"] == "reference"]
    assert len(ref_sims) == main["sims"] and (ref_sims["dem_contender"] == "reference").all()
    assert list(ref_sims["speedup"]) == pytest.approx(list(ref_sims["dem_steps_per_frame"]
                                                          / ref_sims["break_even_steps"]), rel=0.05)
    assert (res / "plots" / "performance_map.png").stat().st_size > 10_000
    # exact switches: same error with and without them
    assert table.at["no_skipping", "mse"] == pytest.approx(main["mse"], rel=1e-4)
    assert pd.isna(table.at["article_size", "mse"]) and not table.at["article_size", "trained"]
    assert table["on_pareto_front"].fillna(False).astype(bool).any()
    assert (res / "plots" / "pareto.png").stat().st_size > 10_000
    assert (res / "timings" / "performance" / "dem_reference.tsv").is_file()
    assert (res / "logs" / "performance" / "surrogate_graphdem.log").is_file()


def test_stability_stage_outputs(workdir):
    import pandas as pd
    res = workdir / "results" / "slide"
    table = pd.read_csv(res / "stability.csv")
    first_test = pd.read_csv(res / "dataset" / "splits.csv").query("split == 'test'")["id"].iloc[0]
    dem = table[table["test"] == "dem_time_step"].set_index("factor")
    assert dem.at[0.5, "stable"] and not dem.at[8.0, "stable"]
    assert dem.at[8.0, "cause"] and dem.at[8.0, "sim"] == first_test and dem.at[8.0, "left_behind"] == 0
    rollouts = table[table["test"] == "surrogate_long_rollout"]
    assert sorted(rollouts["n_frames"]) == [40, 80]                 # 5x and 10x the 8 recorded frames
    assert (rollouts["escaped_particles"] == 0).all()                # keep_in_domain: every particle stays in
    frames = pd.read_csv(res / "stability" / "frames.csv")
    assert sorted(frames.groupby("length")["frame"].max()) == [39, 79]
    assert (frames["outside"] == 0).all() and (frames["kinetic_energy"] >= 0).all()
    for row in rollouts.itertuples():                                # the first frame out of the envelope, named
        out = frames[(frames["length"] == row.factor) & ~frames["in_envelope"]]
        assert row.frames_outside_envelope == len(out)
        assert (pd.isna(row.first_frame_outside_envelope) if out.empty
                else row.first_frame_outside_envelope == out["frame"].iloc[0])
    assert (res / "plots" / "stability.png").stat().st_size > 10_000
    precision = table[table["test"] == "surrogate_precision"].set_index("setting")
    assert precision.at["float64", "max_difference_vs_float64"] == 0
    assert precision.at["float32", "max_difference_vs_float64"] < 1e-3


def test_export_stage_writes_each_test_sim_and_its_rollout_for_paraview(workdir):
    import meshio
    import pandas as pd

    from generators import export
    assert planned(snakemake(workdir, "results/slide/vtk", "-n")) == {"export": 1}     # reuses sims and rollouts
    proc = snakemake(workdir, "results/slide/vtk", "-c1")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    res = workdir / "results" / "slide"
    test_ids = list(pd.read_csv(res / "dataset" / "splits.csv").query("split == 'test'")["id"])
    assert sorted(p.name for p in (res / "vtk").iterdir() if not p.name.startswith(".")) == sorted(test_ids)
    for sim in test_ids:
        truth = h5md.read(res / "sims" / f"{sim}.h5")
        rolled = h5md.read(res / "rollouts" / f"{sim}.h5", allow_nonfinite=True)
        for name, traj in (("dem", truth), ("graphdem", rolled)):
            entries = export.read_pvd(res / "vtk" / sim / f"{name}.pvd")
            assert [t for t, _ in entries] == truth.time.tolist()
            last = meshio.read(entries[-1][1])
            np.testing.assert_array_equal(last.points[:, :2], traj.position[-1])
            np.testing.assert_array_equal(last.points[:, 2], 0.0)
        error = meshio.read(entries[-1][1]).point_data["error"]
        expected = np.linalg.norm(rolled.position[-1].astype(float) - truth.position[-1].astype(float), axis=-1)
        np.testing.assert_allclose(error, expected, rtol=1e-12)
        assert error.max() > 0 and (error[truth.kinematic] == 0).all()
    assert (res / "logs" / "export.log").is_file() and (res / "timings" / "export.tsv").is_file()


def test_changed_learning_rate_retrains_but_reruns_no_engine(workdir):
    jobs = planned(snakemake(workdir, TARGET, "-n", config=(SMALL[:-1] + ", train: {lr: 0.005}}",)))
    assert jobs.get("train") == 1 and jobs.get("evaluate") == 1
    assert not {"prepare", "simulate", "convert", "dataset"} & set(jobs)


def test_unchanged_rerun_does_nothing(workdir):
    assert planned(snakemake(workdir, TARGET, "-n")) == {}


def test_changed_device_or_launcher_reruns_nothing(workdir):
    """Machine settings (docs/scaling.md): where and in how many processes it computes, not what."""
    machine = ("device=cpu", "launch={launcher: torchrun, processes: 2}")
    assert planned(snakemake(workdir, TARGET, "results/slide/performance.csv", "results/slide/stability.csv", "-n",
                             config=(SMALL, *machine))) == {}


def simulated(proc) -> list[str]:
    """The raw folders a dry run's simulate jobs would write."""
    text = proc.stdout + proc.stderr
    return sorted(re.findall(r"^rule simulate:\n(?:    .*\n)*?    output: (\S+)", text, re.M))


def test_changed_weak_friction_reruns_sims_but_not_the_packing(workdir):
    """Every sim reruns, and so do the DEM ensemble's two members of the test sim (they share the sims'
    parameters)."""
    proc = snakemake(workdir, TARGET, "-n", config=(SMALL[:-1] + ", weak_friction: 0.1}",))
    jobs = planned(proc)
    assert jobs.get("simulate") == 5 and jobs.get("convert") == 5 and "prepare" not in jobs
    assert simulated(proc) == [*(f"results/slide/ensemble/m{j}/raw/slide_0000" for j in range(2)),
                               *(f"results/slide/raw/slide_000{i}" for i in range(3))]


def test_changed_history_reruns_only_the_ensemble_members(workdir):
    """The members are perturbed after the last history frame K - 1: a new K reruns them (and retrains), not the
    sims."""
    proc = snakemake(workdir, TARGET, "-n", config=(SMALL[:-1] + ", model: {history: 5}}",))
    assert planned(proc).get("simulate") == 2
    assert simulated(proc) == [f"results/slide/ensemble/m{j}/raw/slide_0000" for j in range(2)]


def test_more_ensemble_members_run_only_the_new_members(workdir):
    proc = snakemake(workdir, TARGET, "-n", config=(SMALL[:-1] + ", evaluate: {ensemble_members: 3}}",))
    jobs = planned(proc)
    assert jobs.get("simulate") == 1 and jobs.get("convert") == 1 and "train" not in jobs
    assert simulated(proc) == ["results/slide/ensemble/m2/raw/slide_0000"]


def test_added_sim_runs_only_that_sim(workdir):
    """The fourth sim is the one the splits give to test, so its ensemble members come with it; nothing else
    runs."""
    proc = snakemake(workdir, TARGET, "-n", config=(SMALL.replace("n_sims: 3", "n_sims: 4"),))
    jobs = planned(proc)
    assert jobs.get("simulate") == 3 and jobs.get("convert") == 3 and "prepare" not in jobs
    assert simulated(proc) == [*(f"results/slide/ensemble/m{j}/raw/slide_0003" for j in range(2)),
                               "results/slide/raw/slide_0003"]


def test_changed_ranks_rerun_nothing_and_new_sims_run_on_them(workdir):
    """`ranks` says how LAMMPS runs, not what it computes: nothing reruns; a new sim's job takes 2 of the
    cores and runs on 2 MPI ranks, or on 1 where Snakemake has 1 core to give."""
    ranks = SMALL[:-1] + ", ranks: 2}"
    assert planned(snakemake(workdir, TARGET, "-n", config=(ranks,))) == {}
    for cores, expected in (("-c2", 2), ("-c1", 1)):
        proc = snakemake(workdir, TARGET, "-n", "-p", cores, config=(ranks.replace("n_sims: 3", "n_sims: 4"),))
        jobs = planned(proc)
        assert jobs.get("simulate") == 3 and "prepare" not in jobs          # the new sim and its 2 ensemble members
        for job in (proc.stdout + proc.stderr).split("rule simulate:")[1:]:
            job = job.split("\nrule ")[0]
            assert ("threads: 2" in job) == (expected == 2), job
            assert f"--ranks {expected} >" in job, job


def test_changed_stiffness_resettles_the_packing(workdir):
    jobs = planned(snakemake(workdir, TARGET, "-n", config=(SMALL[:-1] + ", young: 5.0e9}",)))
    assert jobs.get("prepare") == 1 and jobs.get("simulate") == 3 + 2                # the sims and the ensemble's


@pytest.mark.parametrize("override, expected", [
    ("slide={youngs: 5.0e9}", "unknown config key 'slide.youngs' (did you mean 'young'?); allowed keys under slide"),
    ("slide={frames: 2}", "config key 'slide.frames' = 2 is not allowed"),
    ("slide={engine: matdem}", "'matdem' is not one of ['lammps', 'yade']"),
])
def test_bad_config_stops_before_anything_runs(tmp_path, override, expected):
    proc = snakemake(tmp_path, TARGET, "-n", config=(override,))
    assert proc.returncode != 0
    assert expected in proc.stdout + proc.stderr
    assert not (tmp_path / "results").exists()


@pytest.mark.parametrize("scene", scenes.names())
def test_every_registered_scene_plans_the_benchmark_and_stability_stages(tmp_path, scene):
    """From the scene registry, not from a list: each scene's benchmark has one job per configured
    contender, and its stability stage both tests."""
    cfg = config.load({"scale": "ci"})[scene]
    jobs = planned(snakemake(tmp_path, f"results/{scene}/performance.csv", f"results/{scene}/stability.csv", "-n",
                             config=()))
    assert jobs["performance_dem"] == len(cfg["performance"]["dem"])
    assert jobs["performance_surrogate"] == len(cfg["performance"]["surrogate"])
    assert jobs["performance"] == jobs["stability_dem"] == jobs["stability_surrogate"] == jobs["stability"] == 1
    assert not (tmp_path / "results").exists()


def test_timed_contenders_run_alone_unless_told_otherwise(tmp_path):
    def threads(config):
        proc = snakemake(tmp_path, "results/slide/performance/surrogate/graphdem.csv",
                         "results/slide/performance/dem/dt_10pct_2cores.csv", "-n", "-c2", config=config)
        assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
        out = {}
        for block in proc.stdout.split("\nrule ")[1:]:            # a dry run prints no threads line for 1
            rule = block.split(":", 1)[0]
            found = re.search(r"^    threads: (\d+)$", block.split("\n\n")[0], re.M)
            if rule.startswith("performance_"):
                out[rule] = int(found[1]) if found else 1
        return out
    assert threads(()) == {"performance_surrogate": 2, "performance_dem": 2}          # every core of -c2
    side_by_side = threads(("slide={performance: {alone: false}}",))
    assert side_by_side == {"performance_surrogate": 1, "performance_dem": 2}        # its own: 1 thread, 2 cores


def test_a_run_at_another_scale_is_refused_before_anything_runs(tmp_path):
    (tmp_path / "results" / "slide").mkdir(parents=True)
    (tmp_path / "results" / "slide" / "scale.txt").write_text("default\n")
    proc = snakemake(tmp_path, TARGET, "-c1", config=())           # a real run, not a dry run: nothing starts
    assert proc.returncode != 0
    assert ("results/slide holds results of scale=default; this run asks for scale=ci and would overwrite them"
            in proc.stdout + proc.stderr)
    assert sorted(p.name for p in (tmp_path / "results" / "slide").iterdir()) == ["scale.txt"]
    for target in ("results/slide/sims/slide_0000.h5", "results/crosscheck/slide.csv"):   # not through the sweep
        proc = snakemake(tmp_path, target, "-n", config=())
        assert proc.returncode != 0 and "holds results of scale=default" in proc.stdout + proc.stderr
    assert "sweep" in planned(snakemake(tmp_path, TARGET, "-n", config=("overwrite_scale=true",)))
    # another scene's folder is not this run's business
    assert "sweep" in planned(snakemake(tmp_path, "results/meteorite/dataset/stats.json", "-n", config=()))


SOLIDGN = ROOT.parent / "shared" / "datasets" / "solidgn"
BENCH = "results/slide_small/metrics.csv"


def test_a_benchmark_without_solidgn_root_says_what_to_set(tmp_path):
    proc = snakemake(tmp_path, BENCH, "-n", config=())
    assert proc.returncode != 0
    assert "set the config key 'solidgn_root'" in proc.stdout + proc.stderr
    proc = snakemake(tmp_path, BENCH, "-n", config=(f"solidgn_root={tmp_path / 'nowhere'}",))
    assert proc.returncode != 0 and "has no metadata.json" in proc.stdout + proc.stderr
    assert not (tmp_path / "results").exists()


def test_a_protocol_shorter_than_the_models_history_is_refused(tmp_path):
    proc = snakemake(tmp_path, BENCH, "-n", config=("slide_small={model: {history: 3}}",))
    assert proc.returncode != 0 and "config key 'slide_small.protocols' = [2, 6]" in proc.stdout + proc.stderr
    assert not (tmp_path / "results").exists()


@pytest.mark.parametrize("seeds", [1, 3])
def test_the_benchmarks_target_plans_a_card_per_set_over_the_seeds(tmp_path, seeds):
    """Each set's card reads every seed's evaluation: the main model and seeds - 1 more, per set."""
    root = tmp_path / "solidgn"
    for source in (config.load({"scale": "ci"})[b]["source"] for b in config.BENCHMARKS):
        (root / source).mkdir(parents=True)
        (root / source / "metadata.json").write_text('{"bounds": [[0, 100], [0, 80]], "dim": 2, "dt": 0.001}')
    jobs = planned(snakemake(tmp_path / "work", "benchmarks", "-n", config=(f"solidgn_root={root}", f"seeds={seeds}")))
    n = len(config.BENCHMARKS)
    assert jobs["card"] == jobs["train"] == jobs["evaluate"] == jobs["import_solidgn"] == n
    assert jobs.get("train_seed", 0) == jobs.get("evaluate_seed", 0) == n * (seeds - 1)
    assert jobs.get("evaluate_seed_ensemble", 0) == (n if seeds > 1 else 0)      # the seeds' models as one
    assert "seeds" not in jobs                       # the card reads the seeds' tables itself, not seeds.csv
    proc = snakemake(tmp_path / "work", "results/slide/card.md", "-n", config=(f"solidgn_root={root}",))
    assert proc.returncode != 0 and "no rule makes 'results/slide/card.md'" in proc.stdout + proc.stderr


@pytest.mark.skipif(not SOLIDGN.is_dir(), reason="the Solid-GN data is not beside this checkout")
def test_slide_small_benchmark_runs_both_protocols_on_valid(tmp_path):
    proc = snakemake(tmp_path, BENCH, "results/slide_small/card.md", "-c2",
                     config=(f"solidgn_root={SOLIDGN}", "seeds=2"))
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    import pandas as pd

    from evaluation.tables import read_csv
    res = tmp_path / "results" / "slide_small"
    table = read_csv(res / "metrics.csv")                 # the digest as text, whatever its characters
    mse = table[(table["metric"] == "rollout MSE") & (table["sim"] == "all")]
    assert sorted(mse["history"].unique()) == [2, 6]
    assert set(mse["method"]) == {"graphdem", "constant_velocity"}
    assert set(table["split"]) == {"valid"} and table["split_note"].str.contains("no test split").all()
    frames = mse.set_index(["method", "history"])["n_frames"]
    assert frames[("constant_velocity", 2)] == 3 * 18 and frames[("constant_velocity", 6)] == 3 * 14
    best = res / "model" / "best.pt"                  # one model serves both protocols
    meta = __import__("surrogate.checkpoint", fromlist=["load"]).load(best)["json"]
    assert meta["model"]["history"] == 2 and meta["model"]["properties"] == ["radius"]
    assert meta["stats"]["n_train_sims"] == 6
    assert set(table["checkpoint_sha"]) == {__import__("surrogate.checkpoint", fromlist=["digest"]).digest(best)}
    assert (res / "timings" / "train.tsv").is_file() and (res / "logs" / "train.log").is_file()
    steps = pd.read_csv(res / "metrics_per_step.csv")
    assert set(steps["history"]) == {2, 6}
    assert (res / "plots" / "rollout.gif").is_file() and (res / "plots" / "metrics_over_frames.png").is_file()
    assert (res / "timings" / "evaluate.tsv").is_file()
    # the benchmark card over seeds 0 and 1: both methods under both protocols, the article's figures from the config
    steps = steps[steps["sim"] == "all"]
    assert sorted(steps.groupby("history")["tau"].max().items()) == [(2, 18), (6, 14)]   # each K's own mean rows
    assert set(pd.read_csv(res / "seeds" / "1" / "metrics_per_step.csv")["history"]) == {2, 6}
    card = pd.read_csv(res / "card.csv")
    ours = card[card["source"] == "measured"]
    assert set(ours["n_seeds"]) == {2} and set(ours["split"].dropna()) == {"valid"}
    cost = ours[ours["quantity"] == "train_cost"].set_index("method")["mean"]
    assert cost["seed_ensemble"] == pytest.approx(2 * cost["graphdem"], rel=1e-6)   # sum of 2 models = 2 x mean
    together = ours[(ours["method"] == "seed_ensemble") & (ours["quantity"] == "rollout_mse")]
    assert len(together) == 2 and np.isfinite(together["mean"]).all() and set(together["n_seeds"]) == {2}
    assert "| seed ensemble |" in (res / "card.md").read_text()
    ours = ours[ours["method"] != "seed_ensemble"]
    per_k = ours.dropna(subset=["history"])
    pairs = set(zip(per_k["method"], per_k["history"], strict=True))
    assert pairs == {(m, k) for m in ("graphdem", "constant_velocity") for k in (2, 6)}
    mse = per_k[(per_k["quantity"] == "rollout_mse")].set_index(["method", "history"])
    main = table[(table["metric"] == "rollout MSE") & (table["sim"] == "all")].set_index(["method", "history"])["mse"]
    assert mse.loc[("constant_velocity", 2), "mean"] == pytest.approx(main[("constant_velocity", 2)])
    assert mse.loc[("graphdem", 2), "values"].startswith(f"0:{main[('graphdem', 2)]:.6g} ")   # seed 0: the main model
    assert mse.loc[("graphdem", 2), "n_predicted"] == 18 and mse.loc[("graphdem", 6), "n_predicted"] == 14
    radius = json.loads((res / "dataset" / "stats.json").read_text())["property_stats"]["radius"]["mean"]
    rmse = per_k[per_k["quantity"] == "rmse_diameters"].set_index(["method", "history"])
    assert rmse.loc[("graphdem", 2), "mean"] == pytest.approx(np.mean(
        [float(v.split(":")[1]) ** 0.5 / (2 * radius) for v in mse.loc[("graphdem", 2), "values"].split()]), rel=1e-4)
    cost = ours[ours["quantity"] == "train_cost"].iloc[0]
    assert cost["unit"] in {"core-hours", "GPU-hours"} and cost["mean"] > 0 and cost["n_seeds"] == 2
    article = card[card["source"] == "article"].set_index(["method", "quantity"])["mean"]
    want = config.load({"scale": "ci"})["slide_small"]["article"]["rollout_mse"]
    assert {m: article[(m, "rollout_mse")] for m in want} == want
    text = (res / "card.md").read_text()
    assert "**valid** split" in text and "Training hardware: " in text and "| Graph-DEM |" in text
    assert (res / "logs" / "card.log").is_file() and (res / "timings" / "card.tsv").is_file()


@pytest.mark.parametrize("scene, dim, n_types, metrics", [
    ("meteorite", 2, 2, {"Imp Dep", "Cra Dep", "Imp R(L)", "Imp R(R)", "Sp Num(L)", "Sp Num(R)", "Max Ht(L)",
                      "Max Ht(R)", "Mean Ht(L)", "Mean Ht(R)"}),
    ("shear", 3, 3, {"Mean x", "Above sum", "Above mean", "Below sum", "Below mean", "Failure Surface sum",
                  "Failure Surface mean", "All sum", "All mean"}),
])
def test_scene_outputs(ci_results, scene, dim, n_types, metrics):
    import pandas as pd
    res = ci_results / scene
    stats = json.loads((res / "dataset" / "stats.json").read_text())
    assert stats["dim"] == dim and stats["n_types"] == n_types       # shear: box, soil and the load platen
    table = pd.read_csv(res / "metrics.csv", dtype={"acc_frames": str})      # a one-tau list reads as text
    assert metrics | {"rollout MSE"} <= set(table["metric"])
    mse = table[(table["metric"] == "rollout MSE") & (table["sim"] == "all")].set_index("method")["mse"]
    assert np.isfinite(mse["graphdem"]) and mse["graphdem"] > 0 and np.isfinite(mse["constant_velocity"])
    # the DEM ensemble: each test sim replayed to its last history frame and perturbed there by 1e-5 radii differs
    # from it, but by far less than extrapolation does (the chaos floor); two members per test sim at the ci scale
    assert 0 < mse["dem_ensemble"] < mse["constant_velocity"]
    scored = sorted(table.loc[(table["metric"] == "rollout MSE") & (table["sim"] != "all"), "sim"].unique())
    for j in range(2):
        assert sorted(p.stem for p in (res / "ensemble" / f"m{j}" / "sims").glob("*.h5")) == scored
    steps = pd.read_csv(res / "metrics_per_step.csv")
    assert set(steps["method"]) == {"graphdem", "constant_velocity", "dem_ensemble", "dem_ensemble_mean"}
    overall = table[table["sim"] == "all"].set_index(["method", "metric"])
    # plausibility: the DEM's own overlaps stay below its blow-up limit, and no DEM particle leaves the box or
    # passes a wall (the shear's box and platen; the meteorite has no wall particle)
    for method in ("dem_ensemble", "graphdem"):
        assert 0 < overall.at[(method, "Max overlap"), "mean_truth"] < 0.5
        assert overall.at[(method, "Outside box"), "mean_truth"] == 0
        assert overall.at[(method, "Through wall"), "mean_truth"] == 0
    assert overall.at[("dem_ensemble", "Outside box"), "mean_prediction"] == 0
    assert overall.at[("dem_ensemble", "Through wall"), "mean_prediction"] == 0
    # the article's frame set: the meteorite's Acc averages over Table 2's taus that its ci window reaches
    frames = set(overall.loc[(slice(None), sorted(metrics & set(overall.index.get_level_values(1)))),
                             "acc_frames"].dropna())
    n_predicted = int(steps["tau"].max())
    if scene == "meteorite":
        want = " ".join(str(t) for t in (5, 10, 15, 20, 30) if t <= n_predicted)
        assert frames <= {want} and frames
    else:
        assert frames <= {f"1-{n_predicted}"}
    for name in ("metrics_over_frames.png", "rollout.gif", "dataset_sample.png"):
        assert (res / "plots" / name).stat().st_size > 5_000
    for rule in ("sweep", "dataset", "train", "evaluate"):
        assert (res / "timings" / f"{rule}.tsv").is_file() and (res / "logs" / f"{rule}.log").is_file()
    assert (res / "scale.txt").read_text() == "ci\n"         # the folder records the scale it was built at


def test_shear_property_and_log_scaling_reach_the_dataset(ci_results):
    stats = json.loads((ci_results / "shear" / "dataset" / "stats.json").read_text())
    assert stats["property_names"] == ["young", "normal_stress"] and stats["kinematic_species"] == [0, 2]
    assert stats["property_stats"]["young"]["log"] is True
    assert stats["property_stats"]["normal_stress"]["log"] is True
    meteorite = json.loads((ci_results / "meteorite" / "dataset" / "stats.json").read_text())
    assert meteorite["property_names"] == [] and meteorite["kinematic_species"] == []


def test_shear_stress_check_reads_the_test_sims_stress_beside_the_dems_observable(ci_results):
    """shear_stress.csv: the readout trained on the train split (chosen on valid) reads each test sim's stress; the
    DEM's and the ensemble's peaks are their observables' largest values over the predicted frames, the Coulomb floor's
    the test sim's normal stress times the train sims' mean peak stress ratio."""
    import pandas as pd

    from evaluation import shear_stress
    res = ci_results / "shear"
    splits = pd.read_csv(res / "dataset" / "splits.csv")
    ids = list(splits.query("split == 'test'")["id"])
    table = pd.read_csv(res / "shear_stress.csv")
    assert list(table["sim"]) == [*ids, "all"]
    k = int(table["history"].iloc[0])
    assert k == config.load({"scale": "ci"})["shear"]["model"]["history"]
    # the Coulomb floor: sigma_n x the train sims' mean peak of tau / sigma_n over the same frames
    train_ratio = []
    for sim in splits.query("split == 'train'")["id"]:
        traj = h5md.read(res / "sims" / f"{sim}.h5")
        train_ratio.append(traj.observables["shear_stress"][k:].max() / traj.parameters["normal_stress"])
    for sim in ids:
        row = table.set_index("sim").loc[sim]
        truth = h5md.read(res / "sims" / f"{sim}.h5")
        member = h5md.read(res / "ensemble" / "m0" / "sims" / f"{sim}.h5")       # the first member
        assert row["coulomb_peak"] == pytest.approx(truth.parameters["normal_stress"] * np.mean(train_ratio), rel=1e-9)
        assert row["dem_peak"] == pytest.approx(truth.observables["shear_stress"][k:].max(), rel=1e-9)
        assert row["ensemble_peak"] == pytest.approx(member.observables["shear_stress"][k:].max(), rel=1e-9)
        assert row["normal_stress"] == truth.parameters["normal_stress"]
        for name in ("readout", "graphdem", "cv", "coulomb"):
            assert np.isfinite(row[f"{name}_peak"]) and np.isfinite(row[f"{name}_rmse"])
            assert row[f"{name}_error"] == pytest.approx(row[f"{name}_peak"] / row["dem_peak"] - 1)
    _, meta = shear_stress.load(res / "shear_stress" / "readout.pt")
    assert meta["train_sims"] == list(splits.query("split == 'train'")["id"])
    assert meta["valid_sims"] == list(splits.query("split == 'valid'")["id"])
    history = pd.read_csv(res / "shear_stress" / "history.csv")
    assert len(history) == config.load({"scale": "ci"})["shear"]["shear_stress_readout"]["epochs"]
    assert meta["valid_mse"] == pytest.approx(history["valid_mse"].min())
    assert (res / "plots" / "shear_stress.png").stat().st_size > 10_000
    for stage in ("shear_stress_readout", "shear_stress_check"):
        assert (res / "logs" / f"{stage}.log").is_file() and (res / "timings" / f"{stage}.tsv").is_file()


def test_shear_property_sensitivity_reruns_each_test_sim_at_two_moduli_all_else_kept(ci_results):
    """Article Fig. 14: the DEM reruns differ from the test sim in the modulus alone, the stiffer soil is
    compressed less by the same platen load, and property_sensitivity.csv compares the DEM's change with the
    model's."""
    import pandas as pd

    from generators import property_sensitivity
    res = ci_results / "shear"
    low, high = property_sensitivity.values("shear", config.load({"scale": "ci"})["shear"])
    ids = list(pd.read_csv(res / "dataset" / "splits.csv").query("split == 'test'")["id"])
    table = pd.read_csv(res / "property_sensitivity.csv")
    assert list(table["sim"]) == [*ids, "all"] and set(table["property"]) == {"young"}
    for sim in ids:
        base = h5md.read(res / "sims" / f"{sim}.h5")
        runs = [h5md.read(res / "property" / str(i) / "sims" / f"{sim}.h5") for i in (0, 1)]
        for run, value in zip(runs, (low, high), strict=True):
            column = run.property_names.index("young")
            assert set(run.properties[:, column]) == {value}
            assert run.parameters["normal_stress"] == base.parameters["normal_stress"]
            assert np.array_equal(run.species, base.species) and np.array_equal(run.radius, base.radius)
        platen = base.species == shear.PLATEN
        soft, stiff = (run.position[0, platen, 2].mean() for run in runs)
        assert stiff > soft                        # the same load presses the stiffer soil less far
        row = table.set_index("sim").loc[sim]
        dem = [run.position[-1, ~run.kinematic, 0].astype(np.float64).mean() for run in runs]
        assert row["dem_delta"] == pytest.approx(dem[1] - dem[0], rel=1e-6, abs=1e-12)
        assert np.isfinite(row["graphdem_delta"]) and row["chaos_delta"] >= 0
    assert (res / "plots" / "property_sensitivity.png").stat().st_size > 10_000
    assert (res / "logs" / "property_sensitivity.log").is_file()
    assert (res / "timings" / "property_sensitivity.tsv").is_file()
