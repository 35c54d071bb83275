import numpy as np
import pytest

from evaluation.metrics import accuracy, curve_accuracy, frame_list


def test_acc_divides_by_the_truth():
    acc, left_out = accuracy([10.0, 20.0], [9.0, 25.0])     # 90 % and 75 %
    assert acc == pytest.approx(82.5) and left_out == 0


def test_zero_truth_frames_are_left_out_and_counted():
    acc, left_out = accuracy([0.0, 4.0, 0.0, 2.0], [3.0, 3.0, 0.0, 2.0])   # only frames 1 and 3: 75 %, 100 %
    assert acc == pytest.approx(87.5) and left_out == 2


def test_an_undefined_value_on_either_side_is_left_out_alike_never_scored_zero():
    acc, left_out = accuracy([np.nan, 5.0, 5.0, 4.0], [1.0, np.nan, 5.0, 3.0])   # only 100 % and 75 % are scored
    assert acc == pytest.approx(87.5) and left_out == 2


def test_accuracy_can_be_negative_when_the_error_exceeds_the_truth():
    assert accuracy([1.0], [3.5])[0] == pytest.approx(-150.0)


def test_all_frames_left_out_gives_nan():
    acc, left_out = accuracy([0.0, 0.0], [1.0, 2.0])
    assert np.isnan(acc) and left_out == 2


# ---- the article's way: Acc of the test-set mean curve -------------------------------------------------

# Table 2 of the article (meteorite, T = 5, 10, 15, 20, 30): truth and prediction columns, and the Acc row.
TABLE2 = {
    "Imp Dep": ([37.63, 52.27, 65.93, 78.51, 95.58], [37.52, 52.02, 65.11, 77.06, 94.00], 98.90),
    "Imp R(L)": ([35.69, 47.39, 58.27, 69.31, 88.32], [35.92, 47.71, 59.00, 69.49, 89.62], 99.14),
    "Imp R(R)": ([34.07, 46.75, 57.99, 69.75, 88.70], [33.78, 45.66, 55.80, 66.36, 83.72], 96.51),
    "Sp Num(L)": ([5.46, 5.60, 8.94, 13.86, 27.09], [5.60, 5.73, 8.95, 13.52, 25.47], 97.31),
    "Sp Num(R)": ([5.01, 4.84, 7.45, 11.65, 24.91], [5.01, 4.68, 6.89, 10.57, 21.96], 93.61),
    "Cra Dep": ([11.20, 15.54, 20.69, 24.99, 32.21], [11.24, 15.62, 21.04, 25.78, 33.08], 98.31),
    "Max Ht(L)": ([4.28, 9.52, 17.12, 25.23, 42.42], [4.33, 9.63, 17.35, 25.47, 42.25], 99.00),
    "Max Ht(R)": ([3.84, 8.49, 15.94, 23.77, 40.01], [3.78, 8.48, 15.91, 23.69, 39.65], 99.38),
    "Mean Ht(L)": ([2.52, 4.21, 6.63, 9.03, 12.92], [2.56, 4.21, 6.55, 8.93, 12.97], 99.14),
    "Mean Ht(R)": ([2.41, 4.20, 6.53, 8.21, 10.97], [2.37, 4.21, 6.59, 8.41, 11.06], 98.79),
}
# Table 3 (slide, tau = 1..14).
TABLE3 = {
    "Slide Num": ([144.82, 175.59, 194.90, 209.18, 220.28, 229.03, 236.29, 241.49, 246.58, 248.91, 250.99, 252.13,
                   253.46, 253.52],
                  [138.55, 169.36, 186.60, 200.28, 210.23, 217.97, 224.43, 230.02, 234.86, 238.98, 242.50, 246.11,
                   249.87, 253.75], 96.32),
    "Max Ht": ([51.80, 51.41, 50.76, 49.60, 48.34, 46.76, 45.45, 44.34, 43.53, 42.78, 42.03, 41.49, 41.02, 40.67],
               [51.70, 51.54, 50.77, 49.54, 48.03, 46.51, 45.02, 43.78, 42.69, 41.70, 40.81, 40.20, 39.69, 39.32],
               98.50),
    "Mean Ht": ([26.38, 24.81, 23.32, 22.13, 21.26, 20.46, 19.92, 19.49, 19.12, 18.88, 18.66, 18.52, 18.39, 18.33],
                [26.79, 25.03, 23.75, 22.74, 21.87, 21.17, 20.61, 20.09, 19.68, 19.32, 19.01, 18.76, 18.48, 18.22],
                97.90),
    "Tongue Dis": ([48.15, 52.03, 55.29, 57.48, 60.36, 63.09, 64.50, 66.22, 67.67, 68.26, 68.91, 69.37, 69.82, 69.90],
                   [47.82, 51.89, 54.61, 57.17, 59.23, 61.47, 63.02, 64.01, 64.99, 66.12, 66.95, 67.45, 67.90, 69.00],
                   97.89),
}


@pytest.mark.parametrize("table,frames", [(TABLE2, [5, 10, 15, 20, 30]), (TABLE3, list(range(1, 15)))],
                         ids=["table2", "table3"])
def test_curve_accuracy_reproduces_the_articles_tables_from_their_own_columns(table, frames):
    """The article's Acc rows follow from its truth and prediction columns to the 0.01 points it prints."""
    for name, (truth, prediction, printed) in table.items():
        result = curve_accuracy(np.array(frames), np.array(truth), np.array(prediction), frames)
        assert round(result.acc, 2) == pytest.approx(printed, abs=1e-9), name
        assert result.frames == tuple(frames) and not result.left_out and not result.missing


def test_curve_accuracy_averages_over_sims_before_comparing():
    """Two sims that err in opposite directions cancel on the mean curve (100 %) but not when pooled (80 %)."""
    tau = np.array([1, 1, 2, 2])
    truth = np.array([10.0, 10.0, 20.0, 20.0])
    prediction = np.array([8.0, 12.0, 16.0, 24.0])
    assert curve_accuracy(tau, truth, prediction).acc == pytest.approx(100.0)
    assert accuracy(truth, prediction)[0] == pytest.approx(80.0)


def test_curve_accuracy_frame_set_zero_truth_missing_taus_and_undefined_predictions():
    tau = np.array([1, 1, 2, 2, 3, 3, 4, 4])
    truth = np.array([0.0, 0.0, 4.0, np.nan, 5.0, 5.0, 2.0, 2.0])
    prediction = np.array([1.0, 1.0, 3.0, 9.0, 5.0, np.nan, 2.0, 2.0])
    # tau 1: mean truth 0, left out; tau 2: only the sim with a defined truth counts (75 %); tau 3: one sim
    # has no prediction, so both means take the other sim only (100 %, counted as undefined); tau 4: exact
    # (100 %); tau 9 is asked for but not reached
    result = curve_accuracy(tau, truth, prediction, [1, 2, 3, 4, 9])
    assert result.acc == pytest.approx((75.0 + 100.0 + 100.0) / 3)
    assert result.frames == (2, 3, 4) and result.left_out == (1,) and result.missing == (9,)
    assert result.undefined_prediction == 1
    only = curve_accuracy(tau, truth, prediction, [4])
    assert only.acc == pytest.approx(100.0) and only.frames == (4,)
    nothing = curve_accuracy(tau, truth, prediction, [1, 9])
    assert np.isnan(nothing.acc) and nothing.frames == ()


def test_frame_list_shortens_runs():
    assert frame_list([1, 2, 3, 4]) == "1-4"
    assert frame_list([5, 10, 15, 20, 30]) == "5 10 15 20 30"
    assert frame_list([1, 2, 5, 6, 7]) == "1 2 5-7"
