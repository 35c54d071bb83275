import numpy as np
import pytest

from surrogate.metrics import accuracy


def test_acc_divides_by_the_truth():
    acc, left_out = accuracy([10.0, 20.0], [9.0, 25.0])     # 90 % and 75 %
    assert acc == pytest.approx(82.5) and left_out == 0


def test_zero_truth_frames_are_left_out_and_counted():
    acc, left_out = accuracy([0.0, 4.0, 0.0, 2.0], [3.0, 3.0, 0.0, 2.0])   # only frames 1 and 3: 75 %, 100 %
    assert acc == pytest.approx(87.5) and left_out == 2


def test_undefined_truth_is_left_out_and_undefined_prediction_scores_zero():
    acc, left_out = accuracy([np.nan, 5.0, 5.0], [1.0, np.nan, 5.0])
    assert acc == pytest.approx(50.0) and left_out == 1


def test_accuracy_can_be_negative_when_the_error_exceeds_the_truth():
    assert accuracy([1.0], [3.5])[0] == pytest.approx(-150.0)


def test_all_frames_left_out_gives_nan():
    acc, left_out = accuracy([0.0, 0.0], [1.0, 2.0])
    assert np.isnan(acc) and left_out == 2
