"""Direct-shear metrics (Table 4, Fig. 14) on hand-built trajectories with known answers."""

import numpy as np

from generators.scenes.shear import ShearMetrics


def setup():
    """Split plane z_s = 15 mm, band 5 mm. Soil at z = 12, 17, 25 and 14 mm; one box particle."""
    z = np.array([0.012, 0.017, 0.025, 0.014, 0.0])
    kinematic = np.array([False, False, False, False, True])
    truth = np.zeros((3, 5, 3))
    truth[:, :, 2] = z
    truth[:, :, 0] = np.array([0.01, 0.02, 0.03, 0.04, 0.0])
    truth[1:, 4, 0] = 0.5                          # the box moves: it is no soil, never in a set
    return ShearMetrics(kinematic, z, 0.015, 0.005), truth


def test_sets_from_frame_zero_heights():
    metrics, _ = setup()
    sets = metrics.members()
    assert sets["Above"].tolist() == [False, True, False, False, False]
    assert sets["Below"].tolist() == [True, False, False, True, False]
    assert sets["Failure Surface"].tolist() == [True, True, False, True, False]
    assert sets["All"].tolist() == [True, True, True, True, False]


def test_distance_sums_and_means():
    metrics, truth = setup()
    pred = truth.copy()
    pred[:, 0, 0] += 0.003          # Below
    pred[:, 1, 1] += 0.004          # Above
    pred[:, 2, 2] += 0.001          # outside the band
    pred[:, 4, 0] += 1.0            # box: ignored
    d = metrics.compare(pred, truth)
    np.testing.assert_allclose(d["Above sum"], 0.004)
    np.testing.assert_allclose(d["Above mean"], 0.004)
    np.testing.assert_allclose(d["Below sum"], 0.003)
    np.testing.assert_allclose(d["Below mean"], 0.0015)
    np.testing.assert_allclose(d["Failure Surface sum"], 0.007)
    np.testing.assert_allclose(d["Failure Surface mean"], 0.007 / 3)
    np.testing.assert_allclose(d["All sum"], 0.008)
    np.testing.assert_allclose(d["All mean"], 0.002)


def test_mean_x_of_the_soil_only():
    metrics, truth = setup()
    np.testing.assert_allclose(metrics(truth)["Mean x"], 0.025)


def test_blow_up_is_an_infinite_error_and_an_empty_set_is_nan():
    metrics, truth = setup()
    pred = truth.copy()
    pred[2, 3] = np.nan
    d = metrics.compare(pred, truth)
    assert np.isinf(d["All sum"][2]) and np.isfinite(d["All sum"][1])
    narrow = ShearMetrics(metrics.kinematic, metrics.height0, 0.015, 0.0001)
    assert np.isnan(narrow.compare(truth, truth)["Above sum"]).all()
