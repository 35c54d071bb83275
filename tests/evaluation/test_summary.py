import numpy as np
import pandas as pd
import pytest

from evaluation.metrics.scores import Intervals
from evaluation.summary import summarise

INTERVALS = Intervals(samples=400, level=0.95, seed=0)
TAUS = (1, 2, 3)


def rows(method, metric, errors, member=0, truth=10.0, spread=np.nan, blown=()):
    """Per-step rows of two sims (a, b): the truth ``truth`` + tau, the prediction off by ``errors[sim]``."""
    out = []
    for sim, err in errors.items():
        for tau in TAUS:
            t = np.nan if metric == "rollout MSE" else truth + tau
            p = err if metric == "rollout MSE" else t + err * (-1) ** tau      # errors of either sign
            out.append({"scene": "slide", "method": method, "metric": metric, "sim": sim, "member": member,
                        "tau": tau, "frame": 5 + tau, "time": 0.1 * tau, "truth": t,
                        "prediction": np.nan if sim in blown and tau > 1 else p, "blown_up": sim in blown and tau > 1,
                        "truth_start": truth, "spread": spread, "diameter": 0.5})
    return out


def table(metric="Max Ht", spread=0.25, blown=()):
    steps = (rows("graphdem", metric, {"a": 0.1, "b": 0.3}, spread=spread, blown=blown)
             + rows("constant_velocity", metric, {"a": 0.8, "b": 0.8}, spread=spread)
             + rows("dem_ensemble", metric, {"a": 0.2, "b": 0.2}, member=0, spread=spread)
             + rows("dem_ensemble", metric, {"a": 0.4, "b": 0.4}, member=1, spread=spread))
    out = summarise(pd.DataFrame(steps), intervals=INTERVALS, units={"Max Ht": "m", "Slide Num": "particles"})
    return out[out["sim"] == "all"].set_index("method")


def test_change_error_skill_spreads_and_members_of_a_length_metric():
    t = table()
    model = t.loc["graphdem"]
    assert model["change_error"] == pytest.approx(0.2)                     # mean of 0.1 and 0.3
    assert model["change_scale_kind"] == "mean diameter" and model["change_scale"] == pytest.approx(0.5)
    assert model["change_error_scaled"] == pytest.approx(0.4)               # 0.2 m in diameters of 0.5 m
    assert model["skill"] == pytest.approx(1 - 0.2 / 0.8)
    assert model["skill_ci_low"] <= model["skill"] <= model["skill_ci_high"] <= 1 - 0.1 / 0.8 + 1e-12
    assert model["change_error_ci_low"] >= 0.1 - 1e-12 and model["change_error_ci_high"] <= 0.3 + 1e-12
    assert model["ensemble_spread"] == pytest.approx(0.25) and model["error_in_spreads"] == pytest.approx(0.8)
    members = t.loc["dem_ensemble"]
    assert members["change_error"] == pytest.approx(0.3) and members["n_members"] == 2
    assert members["member_sd"] == pytest.approx(np.std([0.2, 0.4], ddof=1))
    assert model["vs_members"] == pytest.approx(0.2 / 0.3)
    assert t.loc["constant_velocity", "skill"] == pytest.approx(0.0)


def test_the_articles_acc_averages_errors_of_opposite_sign_away_and_the_change_error_does_not():
    t = table()
    # the model errs +-0.1 and +-0.3 in alternating signs: on the mean curve the sims' errors add up, per tau,
    # to +-0.2 of a truth of 11-13 m, i.e. Acc near 98.4 %, while the change error stays 0.2 m
    assert t.loc["graphdem", "acc_percent"] == pytest.approx(100 * (1 - np.mean([0.2 / 11, 0.2 / 12, 0.2 / 13])))
    assert t.loc["graphdem", "acc_frames"] == "1-3"


def test_a_count_is_scaled_by_the_truths_change():
    t = table("Slide Num")
    model = t.loc["graphdem"]
    assert model["change_scale_kind"] == "truth change"
    assert model["change_scale"] == pytest.approx(2.0)                      # mean of |tau| over tau 1..3
    assert model["change_error_scaled"] == pytest.approx(0.1)


def test_the_rollout_mse_in_spreads_is_the_root_of_mse_over_the_members_variance():
    t = table("rollout MSE", spread=0.05)
    model = t.loc["graphdem"]
    assert model["mse"] == pytest.approx(0.2) and model["skill"] == pytest.approx(0.75)
    assert model["error_in_spreads"] == pytest.approx(np.sqrt(0.2 / 0.05))
    assert model["vs_members"] == pytest.approx(0.2 / 0.3)


def test_a_blown_up_rollout_leaves_its_figures_undefined_and_named():
    t = table(blown=("b",))
    model = t.loc["graphdem"]
    assert np.isnan(model["change_error"]) and np.isnan(model["skill"]) and np.isnan(model["acc_percent"])
    assert model["n_blown_up"] == 1 and model["blown_up_sims"] == "b"
    assert t.loc["constant_velocity", "n_blown_up"] == 0 and np.isfinite(t.loc["constant_velocity", "change_error"])
