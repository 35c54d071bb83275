import numpy as np
import pytest

from evaluation.metrics import curve_accuracy, scores
from tests.evaluation.metrics.test_accuracy import TABLE2, TABLE3


def curves(truth, prediction, start=None) -> scores.Curves:
    truth = np.asarray(truth, float)
    prediction = np.asarray(prediction, float)
    if prediction.ndim == 2:
        prediction = prediction[:, None, :]
    start = np.full(len(truth), np.nan) if start is None else np.asarray(start, float)
    return scores.Curves(tuple(f"s{i}" for i in range(len(truth))), np.arange(1, truth.shape[1] + 1), truth, prediction,
                  start)


def test_the_change_error_does_not_depend_on_where_zero_is():
    """A height error is the same 0.5 m whether the heights are measured from 0 m or from 1000 m; Acc is not."""
    truth = np.array([[2.0, 3.0, 4.0]])
    prediction = truth + np.array([[0.5, -0.5, 0.5]])
    low, high = curves(truth, prediction), curves(truth + 1000.0, prediction + 1000.0)
    assert scores.per_sim_change_error(low) == pytest.approx([0.5])
    assert scores.per_sim_change_error(high) == pytest.approx([0.5])
    assert scores.curve_acc(high, None)[0][0] > 99.9 > scores.curve_acc(low, None)[0][0]


def test_the_truths_change_is_measured_from_the_last_given_frame():
    c = curves([[12.0, 14.0, 10.0]], [[12.0, 14.0, 10.0]], start=[10.0])
    assert scores.per_sim_truth_change(c) == pytest.approx([(2.0 + 4.0 + 0.0) / 3])


def test_undefined_values_are_skipped_when_both_and_counted_when_one_side():
    truth = [[1.0, np.nan, 3.0, np.nan]]
    prediction = [[2.0, np.nan, np.nan, 5.0]]
    c = curves(truth, prediction)
    assert scores.per_sim_change_error(c) == pytest.approx([1.0])          # only tau 1 has both
    assert scores.undefined(c) == (1, 1, ["s0"])                            # tau 3: no prediction; tau 4: no truth


def test_members_are_averaged_within_their_sim_and_each_sim_weighs_the_same():
    truth = np.zeros((2, 2))
    prediction = np.zeros((2, 3, 2))
    prediction[0] = [[1.0, 1.0], [3.0, 3.0], [2.0, 2.0]]          # sim 0: members err 1, 3, 2 -> 2
    prediction[1] = 4.0                                              # sim 1: 4
    c = scores.Curves(("a", "b"), np.array([1, 2]), truth, prediction, np.zeros(2))
    assert scores.per_sim_change_error(c) == pytest.approx([2.0, 4.0])


@pytest.mark.parametrize("table,frames", [(TABLE2, [5, 10, 15, 20, 30]), (TABLE3, list(range(1, 15)))],
                         ids=["table2", "table3"])
def test_the_vectorised_curve_acc_reproduces_the_articles_tables(table, frames):
    for name, (truth, prediction, printed) in table.items():
        c = scores.Curves(("all",), np.array(frames), np.array([truth]), np.array([[prediction]]), np.array([np.nan]))
        acc, scored = scores.curve_acc(c, frames)
        assert round(float(acc[0]), 2) == pytest.approx(printed, abs=1e-9), name
        assert scored[0].all()


def test_curve_acc_agrees_with_curve_accuracy_on_several_sims_with_gaps():
    rng = np.random.default_rng(3)
    truth = rng.uniform(1.0, 5.0, (6, 5))
    truth[2, 1] = np.nan
    prediction = truth + rng.normal(0.0, 0.3, truth.shape)
    prediction[4, 3] = np.nan
    c = curves(truth, prediction)
    tau = np.tile(c.taus, 6)
    reference = curve_accuracy(tau, truth.ravel(), prediction.ravel(), [1, 2, 4, 5])
    acc, scored = scores.curve_acc(c, [1, 2, 4, 5])
    assert acc[0] == pytest.approx(reference.acc) and tuple(c.taus[scored[0]]) == reference.frames


def test_bootstrap_intervals_bracket_the_mean_shrink_with_more_sims_and_repeat_with_the_seed():
    intervals = scores.Intervals(samples=2000, level=0.95, seed=7)
    rng = np.random.default_rng(0)
    few, many = rng.normal(1.0, 0.5, 10), rng.normal(1.0, 0.5, 160)
    mean, low, high = scores.mean_and_interval(few, intervals.draws(10), intervals)
    assert low < mean < high and mean == pytest.approx(few.mean())
    _, low_many, high_many = scores.mean_and_interval(many, intervals.draws(160), intervals)
    assert (high_many - low_many) < 0.5 * (high - low)              # about sqrt(16) = 4 times narrower
    # the standard error of a mean of 10 draws of sd 0.5 is 0.16: a 95 % interval about 0.6 wide
    assert 0.4 < high - low < 0.9
    assert scores.mean_and_interval(few, intervals.draws(10), intervals) == (mean, low, high)


def test_a_nan_sim_makes_the_figure_nan_rather_than_being_averaged_away():
    intervals = scores.Intervals(100, 0.9, 0)
    assert all(np.isnan(v) for v in scores.mean_and_interval(np.array([1.0, np.nan]), intervals.draws(2), intervals))


def test_skill_is_one_minus_the_error_ratio_paired_on_the_same_sims():
    intervals = scores.Intervals(500, 0.95, 1)
    model, reference = np.array([1.0, 2.0, 3.0]), np.array([4.0, 4.0, 4.0])
    skill, low, high = scores.skill_and_interval(model, reference, intervals.draws(3), intervals)
    assert skill == pytest.approx(0.5) and low <= 0.5 <= high and 0.25 <= low and high <= 0.75
    worse = scores.skill_and_interval(reference * 2, reference, intervals.draws(3), intervals)
    assert worse[0] == pytest.approx(-1.0)


@pytest.mark.parametrize("bad,match", [(dict(samples=0), "samples"), (dict(samples=2.5), "samples"),
                                       (dict(level=1.0), "level"), (dict(seed=-1), "seed")])
def test_bad_interval_settings_are_refused_by_name(bad, match):
    with pytest.raises(ValueError, match=f"intervals.{match}"):
        scores.Intervals(**{"samples": 100, "level": 0.95, "seed": 0, **bad})
