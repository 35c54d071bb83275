"""The property-sensitivity test (article Fig. 14): the change of the moving particles' mean x between two reruns
that differ in one property, DEM against Graph-DEM, on hand-made trajectories whose answer is known."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from evaluation import property_sensitivity
from generators import h5md
from graphdem.cli import main
from surrogate import checkpoint

SHA = "feedfacecafe"
K = 2
UM = 2e-8        # positions are stored in float32: a mean x of ~0.03 m is good to about 1e-8 m


def trajectory(shift: float, young: float, frames: int = 5, n_moving: int = 6, seed: int = 0,
               parameters: dict | None = None) -> h5md.Trajectory:
    """``n_moving`` spheres in 3D moving along +x by ``shift`` more per frame than a base speed of 1 mm per frame,
    and two kinematic ones that stay; every particle carries the property young."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(0.0, 0.05, (n_moving, 3))
    drift = (1e-3 + shift) * np.arange(frames)[:, None, None] * np.array([1.0, 0.0, 0.0])
    moving = start[None] + drift
    fixed = np.broadcast_to(np.array([[0.0, 0.0, -0.01], [0.05, 0.0, -0.01]]), (frames, 2, 3))
    position = np.concatenate([moving, fixed], axis=1)
    n = position.shape[1]
    kinematic = np.arange(n) >= n_moving
    return h5md.Trajectory(position=position, time=np.arange(frames) * 1e-3, step=np.arange(frames) * 10,
                           species=np.where(kinematic, 0, 1), radius=np.full(n, 4e-3), mass=np.ones(n),
                           kinematic=kinematic, box_lower=np.full(3, -0.1), box_upper=np.full(3, 0.2),
                           properties=np.full((n, 1), young), property_names=("young",),
                           parameters=dict(parameters or {}))


def write_run(run: Path, sim: str, young: float, truth_shift: float, predicted_shift: float, sha: str = SHA) -> None:
    h5md.write(run / "sims" / f"{sim}.h5", trajectory(truth_shift, young))
    h5md.write(run / "rollouts" / f"{sim}.h5", trajectory(
        predicted_shift, young, parameters={"rollout_checkpoint_sha": sha, "rollout_history": K}))


def test_mean_x_is_over_the_moving_particles_only():
    traj = trajectory(0.0, 1e7, frames=3)
    want = traj.position[:, :6, 0].mean(axis=1)
    np.testing.assert_allclose(property_sensitivity.mean_x(traj.position, traj.kinematic), want)


def test_the_changes_ratio_and_sign_are_the_moved_distances(tmp_path):
    # the stiffer run moves 2 um more per frame in the DEM, 1.5 um more in the prediction: over the 4 frames after
    # frame 0 the mean x differs by 8 um and 6 um, a ratio of 0.75, at the 25 % tolerance's edge
    write_run(tmp_path / "low", "s_0", 1e7, 0.0, 0.0)
    write_run(tmp_path / "high", "s_0", 8e7, 2e-6, 1.5e-6)
    table, pairs = property_sensitivity.run((tmp_path / "low", tmp_path / "high"), ["s_0"], "young", SHA, K, 0.25)
    row = table.set_index("sim").loc["s_0"]
    assert row["dem_delta"] == pytest.approx(8e-6, abs=UM) and row["graphdem_delta"] == pytest.approx(6e-6, abs=UM)
    assert row["ratio"] == pytest.approx(0.75, abs=0.01) and bool(row["same_sign"])
    assert (row["value_low"], row["value_high"], row["frame"]) == (1e7, 8e7, 4)
    assert row["motion"] == pytest.approx(3e-3, abs=UM)              # 1 mm per frame from the last given frame (1) to 4
    assert np.isnan(row["chaos_delta"])                      # no ensemble given
    assert pairs[0].sim == "s_0" and pairs[0].predicted_high.shape == (5, 8, 3)


def test_a_wrong_sign_or_a_change_far_off_fails_the_sim_and_the_summary_counts(tmp_path):
    low, high = tmp_path / "low", tmp_path / "high"
    write_run(low, "s_0", 1e7, 0.0, 0.0)
    write_run(high, "s_0", 8e7, 2e-6, -1e-6)                 # the opposite direction
    write_run(low, "s_1", 1e7, 0.0, 0.0)
    write_run(high, "s_1", 8e7, 2e-6, 2.2e-6)                # 10 % too much: passes
    write_run(low, "s_2", 1e7, 0.0, 0.0)
    write_run(high, "s_2", 8e7, 2e-6, 4e-6)                  # twice the DEM's
    table, _ = property_sensitivity.run((low, high), ["s_0", "s_1", "s_2"], "young", SHA, K, 0.25)
    by_sim = table.set_index("sim")
    assert list(by_sim.loc[["s_0", "s_1", "s_2"], "passed"]) == ["no", "yes", "no"]
    assert not by_sim.at["s_0", "same_sign"] and by_sim.at["s_0", "ratio"] == pytest.approx(-0.5, abs=0.01)
    everything = by_sim.loc["all"]
    assert everything["passed"] == "1 of 3"
    assert everything["dem_delta"] == pytest.approx(8e-6, abs=UM)
    assert everything["graphdem_delta"] == pytest.approx((-4e-6 + 8.8e-6 + 16e-6) / 3, abs=UM)


def test_constant_velocity_is_scored_by_the_same_rule(tmp_path):
    # s_0: the stiffer run is faster from frame 0 on, so the given frames show it and the straight-line
    # extrapolation reproduces the DEM's change exactly (it passes: the test says little there). s_1: both runs
    # move alike through the given frames (0, 1) and the stiffer one gains 2 um per frame only from frame 2: the
    # extrapolation sees no change and fails, while the DEM's change is 6 um.
    low, high = tmp_path / "low", tmp_path / "high"
    write_run(low, "s_0", 1e7, 0.0, 0.0)
    write_run(high, "s_0", 8e7, 2e-6, 2e-6)
    write_run(low, "s_1", 1e7, 0.0, 0.0)
    late = trajectory(0.0, 8e7)
    late.position[2:, :6, 0] += 2e-6 * np.arange(1, 4)[:, None]
    h5md.write(high / "sims" / "s_1.h5", late)
    h5md.write(high / "rollouts" / "s_1.h5", trajectory(1.5e-6, 8e7, parameters={
        "rollout_checkpoint_sha": SHA, "rollout_history": K}))
    table, _ = property_sensitivity.run((low, high), ["s_0", "s_1"], "young", SHA, K, 0.25)
    by_sim = table.set_index("sim")
    assert by_sim.at["s_0", "cv_delta"] == pytest.approx(8e-6, abs=UM)
    assert by_sim.at["s_0", "cv_ratio"] == pytest.approx(1.0, abs=0.01) and by_sim.at["s_0", "cv_passed"] == "yes"
    assert by_sim.at["s_1", "dem_delta"] == pytest.approx(6e-6, abs=UM)
    assert abs(by_sim.at["s_1", "cv_delta"]) < UM and by_sim.at["s_1", "cv_passed"] == "no"
    assert by_sim.at["s_1", "passed"] == "yes"                        # the model's 6 um: ratio 1
    assert by_sim.at["all", "cv_passed"] == "1 of 2" and by_sim.at["all", "passed"] == "2 of 2"
    assert by_sim.at["all", "cv_delta"] == pytest.approx(4e-6, abs=UM)
    assert list(table.columns).index("passed") == list(table.columns).index("motion") + 1


def test_the_dem_chaos_is_the_change_between_a_sim_and_its_ensemble_rerun(tmp_path):
    low, high = tmp_path / "low", tmp_path / "high"
    write_run(low, "s_0", 1e7, 0.0, 0.0)
    write_run(high, "s_0", 8e7, 2e-6, 2e-6)
    h5md.write(tmp_path / "sims" / "s_0.h5", trajectory(0.0, 3e7))
    h5md.write(tmp_path / "ensemble" / "s_0.h5", trajectory(-2.5e-7, 3e7))   # 1 um behind at the last frame
    table, _ = property_sensitivity.run((low, high), ["s_0"], "young", SHA, K, 0.25,
                                        chaos=(tmp_path / "sims", tmp_path / "ensemble"))
    row = table.set_index("sim").loc["s_0"]
    assert row["chaos_delta"] == pytest.approx(1e-6, abs=UM) and row["signal_to_chaos"] == pytest.approx(8.0, rel=0.05)


def test_runs_in_the_wrong_order_other_particles_or_another_models_rollouts_are_refused(tmp_path):
    low, high = tmp_path / "low", tmp_path / "high"
    write_run(low, "s_0", 1e7, 0.0, 0.0)
    write_run(high, "s_0", 8e7, 2e-6, 2e-6)
    with pytest.raises(ValueError, match="give the low value's run first"):
        property_sensitivity.run((high, low), ["s_0"], "young", SHA, K, 0.25)
    with pytest.raises(ValueError, match="made by checkpoint feedfacecafe, not by 0123"):
        property_sensitivity.run((low, high), ["s_0"], "young", "0123", K, 0.25)
    h5md.write(high / "sims" / "s_1.h5", trajectory(0.0, 8e7, n_moving=5))
    h5md.write(high / "rollouts" / "s_1.h5", trajectory(0.0, 8e7, n_moving=5, parameters={
        "rollout_checkpoint_sha": SHA, "rollout_history": K}))
    write_run(low, "s_1", 1e7, 0.0, 0.0)
    with pytest.raises(ValueError, match="hold different particles"):
        property_sensitivity.run((low, high), ["s_1"], "young", SHA, K, 0.25)
    with pytest.raises(ValueError, match="node property 'poisson' is not in the data"):
        property_sensitivity.run((low, high), ["s_0"], "poisson", SHA, K, 0.25)


def test_the_cli_writes_the_table_and_the_figure(tmp_path, capsys):
    model = tmp_path / "best.pt"
    model.write_bytes(b"not a real model: the test only needs its digest")
    sha = checkpoint.digest(model)
    low, high = tmp_path / "property" / "0", tmp_path / "property" / "1"
    write_run(low, "s_0", 1e7, 0.0, 0.0, sha)
    write_run(high, "s_0", 8e7, 2e-6, 1.9e-6, sha)
    out, plot = tmp_path / "property_sensitivity.csv", tmp_path / "property_sensitivity.png"
    assert main(["property-sensitivity", "--checkpoint", str(model), "--runs", str(low), str(high), "--sims", "s_0",
                 "--property", "young", "--history", str(K), "--out", str(out), "--plot", str(plot)]) == 0
    table = pd.read_csv(out)
    assert list(table["sim"]) == ["s_0", "all"] and (table["checkpoint_sha"] == sha).all()
    assert table["ratio"].iloc[0] == pytest.approx(0.95, abs=0.01) and table["passed"].iloc[1] == "1 of 1"
    assert plot.stat().st_size > 10_000
    assert "s_0" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="--sims-dir and --ensemble together"):
        main(["property-sensitivity", "--checkpoint", str(model), "--runs", str(low), str(high), "--sims", "s_0",
              "--property", "young", "--history", str(K), "--out", str(out), "--ensemble", str(low)])
