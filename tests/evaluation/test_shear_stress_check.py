"""The shear-stress check's scoring: peaks over the predicted frames only, signed relative errors, curve RMSE,
the pass rule, and the summary row."""

import numpy as np
import pandas as pd
import pytest

from evaluation import shear_stress_check


def _curve(sim, dem, **predicted):
    full = {name: np.asarray(predicted.get(name, np.full(len(dem), np.nan)), float)
            for name in shear_stress_check.COMPARATORS}
    return shear_stress_check.Curves(sim, np.linspace(0.0, 6e-3, len(dem)), np.asarray(dem, float), full)


def test_peaks_are_taken_over_the_predicted_frames_and_scored_against_the_dems():
    # the DEM's largest value (90) lies in the given frames: the predicted window's peak is 50
    dem = [0, 90, 20, 30, 50, 40]
    curve = _curve("a", dem, readout=[0, 80, 20, 30, 52, 40], graphdem=[np.nan, 0, 25, 35, 44, 40],
                   cv=[0, 0, 60, 70, 80, 90], ensemble=[0, 90, 22, 28, 49, 41])
    row = shear_stress_check.score(curve, history=2, tolerance=0.1, normal_stress=1e4, young=1e7)
    assert row["dem_peak"] == 50
    assert row["readout_peak"] == 52 and row["readout_error"] == pytest.approx(0.04)
    assert row["graphdem_peak"] == 44 and row["graphdem_error"] == pytest.approx(-0.12)
    assert row["cv_peak"] == 90 and row["cv_error"] == pytest.approx(0.8)
    assert row["ensemble_error"] == pytest.approx(-0.02)
    assert row["graphdem_rmse"] == pytest.approx(np.sqrt(np.mean(np.square([5, 5, -6, 0]))))
    assert not row["passed"]                                          # 12 % off, tolerance 10 %
    assert shear_stress_check.score(curve, 2, 0.15, 1e4, 1e7)["passed"]


def test_a_broken_prediction_has_no_rmse_and_the_summary_counts_passes():
    good = _curve("a", [0, 0, 10, 20], readout=[0, 0, 10, 20], graphdem=[0, 0, 10, 21], cv=[0, 0, 10, 30])
    broken = _curve("b", [0, 0, 10, 20], readout=[0, 0, 10, 20], graphdem=[0, 0, np.nan, 19], cv=[0, 0, 5, 5])
    rows = pd.DataFrame([shear_stress_check.score(c, 2, 0.1, 1e4, 1e7) for c in (good, broken)])
    assert np.isnan(rows["graphdem_rmse"].iloc[1]) and rows["graphdem_peak"].iloc[1] == 19   # the finite frames' peak
    assert list(rows["passed"]) == [True, True]
    summary = shear_stress_check.summary(rows, 0.1)
    assert summary["passed"] == "2 of 2 (within 10%)"
    assert summary["graphdem_error"] == pytest.approx(np.mean([0.05, 0.05]))
    assert summary["cv_error"] == pytest.approx(np.mean([0.5, 0.75]))


def test_the_coulomb_floor_peaks_at_sigma_n_times_the_train_sims_mean_peak_ratio():
    # two train sims' tau / sigma_n; K = 2: their peaks over frames 2.. are 0.8 and 0.6 (the 0.9 at frame 1 is given)
    train = [[0.0, 0.9, 0.4, 0.8, 0.7], [0.0, 0.1, 0.2, 0.4, 0.6]]
    floor = shear_stress_check.coulomb(train, normal_stress=2e4, history=2)
    assert floor[2:].max() == pytest.approx(2e4 * 0.7)               # sigma_n x mean(0.8, 0.6)
    mean = np.mean(train, axis=0)
    np.testing.assert_allclose(floor, 2e4 * 0.7 * mean / mean[2:].max())   # the mean curve's shape
    with pytest.raises(ValueError, match="one finite curve per train sim"):
        shear_stress_check.coulomb([[0.0, np.nan, 0.3]], 2e4, 1)
    with pytest.raises(ValueError, match="longer than K = 5"):
        shear_stress_check.coulomb(train, 2e4, 5)


def test_a_readout_without_the_train_ratios_is_refused_with_the_command_that_refits_it():
    refit = "refit it, e.g. snakemake -c2 results/<scene>/shear_stress.csv -R shear_stress_readout"
    with pytest.raises(ValueError, match=refit):
        shear_stress_check.curves(None, {"cutoff": 0.0}, None, np.zeros((3, 2, 3)), 2, None)

