"""metrics.csv: every method's figures over the test sims, beside constant velocity and the DEM ensemble, each with
a bootstrap interval over sims (the yardstick; docs/surrogate.md).

Per method and metric, one ``sim = all`` row, plus the rollout MSE of every sim. The figures
(:mod:`evaluation.metrics.scores` gives each rule):

* rollout MSE (``mse``, only there: its ``mean_prediction`` is empty), and for a metric that compares the
  prediction with the truth frame by frame (the slide's Dis) its mean (``mean_prediction``); for a metric with a
  truth of its own (Max Ht, Runout) the article's Acc (``acc_percent``, kept for the comparison with its tables,
  and ``acc_pooled_percent``) and the datum-free ``change_error`` (metric units), scaled by ``change_scale``
  (``change_scale_kind``: the mean particle diameter for lengths, else the truth's mean change) into
  ``change_error_scaled``;
* ``skill``: 1 - error / constant velocity's error, paired on the same sims (of the MSE, the compared metric or
  the change error);
* the DEM ensemble: ``dem_ensemble`` rows are its members, each scored against the truth (the mean over
  members; ``member_sd``: the figure's standard deviation over members, ``n_members``); ``dem_ensemble_mean``
  scores the members' mean trajectory. ``ensemble_spread`` is the members' own spread (for the MSE their
  positional variance about their mean, m²; for a metric their standard deviation, in its unit), and
  ``error_in_spreads`` every method's error in units of it (for the MSE the root of MSE / variance; within 2:
  as close as the DEM can say). ``vs_members``: the error over the members' mean error;
* ``*_ci_low``/``*_ci_high``: the bootstrap interval of the figure (config ``intervals``);
* ``unit``: the unit of the metric's values (``mse``, ``mean_truth``, ``mean_prediction``, ``change_error``,
  ``change_scale``, ``ensemble_spread``, ``member_sd``), as the module that names the metric gives it
  (:func:`evaluation.metrics.units`); Acc is in percent, skill, ``change_error_scaled``, ``error_in_spreads`` and
  ``vs_members`` are ratios.

A rollout that blew up leaves its figures NaN, its sims named (``blown_up_sims``); an undefined value on one
side only is counted (``n_undefined_prediction``, ``n_undefined_truth``) and named (``undefined_sims``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from evaluation.metrics import frame_list, plausibility
from evaluation.metrics.accuracy import accuracy, curve_accuracy
from evaluation.metrics.scores import (
    Curves,
    Intervals,
    curve_acc,
    mean_and_interval,
    per_sim_change_error,
    per_sim_truth_change,
    skill_and_interval,
    undefined,
)

MSE = "rollout MSE"
BASELINE, ENSEMBLE = "constant_velocity", "dem_ensemble"
LENGTH_UNITS = ("m",)

COLUMNS = ["scene", "method", "metric", "unit", "sim", "acc_percent", "acc_ci_low", "acc_ci_high", "acc_frames",
           "acc_pooled_percent", "mse", "mse_ci_low", "mse_ci_high", "change_error", "change_error_ci_low",
           "change_error_ci_high", "change_scale", "change_scale_kind", "change_error_scaled", "skill",
           "skill_ci_low", "skill_ci_high", "ensemble_spread", "error_in_spreads", "vs_members", "member_sd",
           "n_members", "mean_truth", "mean_prediction", "mean_prediction_ci_low", "mean_prediction_ci_high",
           "n_sims", "n_frames", "n_frames_left_out", "n_undefined_prediction", "n_undefined_truth",
           "undefined_sims", "n_blown_up", "blown_up_sims"]


def default_intervals() -> Intervals:
    """The bootstrap settings of the config's defaults (``intervals``)."""
    from generators import config
    return Intervals(**config.defaults()["intervals"])


def curves_of(group: pd.DataFrame, sims: list[str]) -> Curves:
    """One method's rows of one metric as :class:`Curves` over ``sims`` (members by their index)."""
    taus = np.sort(group["tau"].unique())
    members = int(group["member"].max()) + 1 if "member" in group else 1
    index = {s: i for i, s in enumerate(sims)}
    si = group["sim"].map(index).to_numpy()
    mi = group["member"].to_numpy(int) if "member" in group else np.zeros(len(group), int)
    ti = np.searchsorted(taus, group["tau"].to_numpy())
    prediction = np.full((len(sims), members, len(taus)), np.nan)
    truth = np.full((len(sims), len(taus)), np.nan)
    start = np.full(len(sims), np.nan)
    prediction[si, mi, ti] = group["prediction"].to_numpy(np.float64)
    truth[si, ti] = group["truth"].to_numpy(np.float64)
    if "truth_start" in group:
        start[si] = group["truth_start"].to_numpy(np.float64)
    return Curves(tuple(sims), taus, truth, prediction, start)


def kind_of(metric: str, group: pd.DataFrame) -> str:
    """mse, plausibility, truth (a metric with a truth of its own) or pair (compares prediction with truth)."""
    if metric == MSE:
        return "mse"
    if metric in plausibility.AGGREGATE:
        return "plausibility"
    return "truth" if group["truth"].notna().any() else "pair"


def per_sim(kind: str, c: Curves) -> np.ndarray:
    """[S] the figure per sim: the mean rollout MSE, the mean compared value (Dis) or the change error; a sim with
    a non-finite MSE or an infinite compared value is NaN."""
    if kind == "mse":
        return c.prediction.mean(axis=(1, 2))
    if kind == "truth":
        return per_sim_change_error(c)
    values = c.prediction
    defined = ~np.isnan(values)
    with np.errstate(invalid="ignore"):
        out = np.where(defined, values, 0.0).sum(axis=(1, 2)) / np.maximum(defined.sum(axis=(1, 2)), 1)
    return np.where(np.isinf(values).any(axis=(1, 2)), np.nan, out)


def blown_sims(group: pd.DataFrame, sims: list[str], figure: np.ndarray, kind: str) -> np.ndarray:
    """[S] bool: sims whose rollout blew up (flagged frames, or a non-finite MSE)."""
    flagged = set(group.loc[group["blown_up"].astype(bool), "sim"]) if "blown_up" in group else set()
    out = np.array([s in flagged for s in sims])
    return out | (~np.isfinite(figure) if kind == "mse" else False)


def spread_of(group: pd.DataFrame) -> float:
    """The DEM ensemble members' mean spread of a metric (the same in every method's rows; NaN: no ensemble)."""
    first = group["method"].iloc[0]
    values = group.loc[group["method"] == first, "spread"].to_numpy(np.float64) if "spread" in group else []
    values = np.asarray(values)[np.isfinite(values)]
    return float(values.mean()) if len(values) else float("nan")


def member_sd(kind: str, c: Curves) -> float:
    """The standard deviation over members of a member's figure (mean over sims); NaN for fewer than two."""
    m = c.prediction.shape[1]
    if m < 2:
        return float("nan")
    each = [per_sim(kind, Curves(c.sims, c.taus, c.truth, c.prediction[:, j:j + 1], c.start)).mean()
            for j in range(m)]
    return float(np.std(each, ddof=1))


def change_scale(c: Curves, group: pd.DataFrame, unit: str) -> tuple[float, str]:
    """The scale of a metric's change error: the mean particle diameter for a length, else the truth's mean
    change since the last given frame."""
    if unit in LENGTH_UNITS:
        return float(group.groupby("sim")["diameter"].first().mean()), "mean diameter"
    change = per_sim_truth_change(c)
    change = change[np.isfinite(change)]
    return (float(change.mean()) if len(change) else float("nan")), "truth change"


def value_columns(kind: str) -> str:
    """The name of a kind's main figure: the change error, the MSE or the compared value."""
    return {"truth": "change_error", "mse": "mse", "pair": "mean_prediction"}[kind]


def figure_row(kind: str, method: str, c: Curves, figure: np.ndarray, context: dict) -> dict:
    """The figures of one method and metric (module docstring): its main figure with interval, skill against
    constant velocity, its error in ensemble spreads and against the members."""
    draws, intervals = context["draws"], context["intervals"]
    name = value_columns(kind)
    value, low, high = mean_and_interval(figure, draws, intervals)
    row = {name: value, f"{name}_ci_low": low, f"{name}_ci_high": high}
    reference = context["reference"]
    if reference is not None:
        skill, low, high = skill_and_interval(figure, reference, draws, intervals)
        row.update(skill=skill, skill_ci_low=low, skill_ci_high=high)
    members, spread = context["members"], context["spread"]
    if members is not None and np.isfinite(members).all() and members.mean() > 0:
        row["vs_members"] = value / float(members.mean())
    if np.isfinite(spread) and spread > 0 and kind != "pair":
        row["ensemble_spread"] = spread
        row["error_in_spreads"] = float(np.sqrt(value / spread)) if kind == "mse" else value / spread
    if method == ENSEMBLE:
        row.update(member_sd=member_sd(kind, c), n_members=int(c.prediction.shape[1]))
    return row


def truth_row(c: Curves, group: pd.DataFrame, unit: str, blown: bool, context: dict) -> dict:
    """The article's Acc (of the mean curve, with interval, and pooled), the means it compares, the change
    error's scale and the one-sided undefined pairs of a metric with a truth of its own."""
    frames, draws, intervals = context["frames"], context["draws"], context["intervals"]
    acc, scored = curve_acc(c, frames)
    boot, _ = curve_acc(c, frames, draws)
    truth = np.broadcast_to(c.truth[:, None, :], c.prediction.shape)
    both = c.both & (truth != 0)
    pooled, left_out = accuracy(truth.ravel(), c.prediction.ravel())
    no_pred, no_truth, sims = undefined(c)
    scale, scale_kind = change_scale(c, group, unit)
    row = {"acc_percent": float("nan") if blown else float(acc[0]), "acc_frames": frame_list(c.taus[scored[0]]),
           "acc_pooled_percent": float("nan") if blown else pooled,
           "mean_truth": float(truth[both].mean()) if both.any() else float("nan"),
           "mean_prediction": float(c.prediction[both].mean()) if both.any() else float("nan"),
           "n_frames_left_out": left_out, "n_undefined_prediction": no_pred, "n_undefined_truth": no_truth,
           "undefined_sims": " ".join(sims), "change_scale": scale, "change_scale_kind": scale_kind}
    if not blown:
        row["acc_ci_low"], row["acc_ci_high"] = intervals.interval(boot)
    return row


def metric_rows(metric: str, group: pd.DataFrame, sims: list[str], context: dict) -> list[dict]:
    """The ``sim = all`` row of every method of one metric (and, for the rollout MSE, one row per sim)."""
    kind = kind_of(metric, group)
    methods = {m: g for m, g in group.groupby("method", sort=False)}
    curves = {m: curves_of(g, sims) for m, g in methods.items()}
    figures = {m: per_sim(kind, c) for m, c in curves.items()}
    blown = {m: blown_sims(g, sims, figures[m], kind) for m, g in methods.items()}
    figures = {m: np.where(blown[m], np.nan, f) for m, f in figures.items()}
    context = {**context, "reference": figures.get(BASELINE), "members": figures.get(ENSEMBLE),
               "spread": spread_of(group)}
    rows = []
    for method, part in methods.items():
        c, bad = curves[method], [s for s, b in zip(sims, blown[method], strict=True) if b]
        base = {"scene": part["scene"].iloc[0], "method": method, "metric": metric,
                "unit": context["units"].get(metric, ""), "sim": "all",
                "n_sims": len(sims), "n_frames": int(len(part)), "n_blown_up": len(bad),
                "blown_up_sims": " ".join(bad)}
        if kind == "plausibility":
            rows.append({**base, **plausibility_row(metric, part, context["frames"], bool(bad))})
            continue
        row = {**base, **figure_row(kind, method, c, figures[method], context)}
        if kind == "truth":
            row.update(truth_row(c, part, context["units"].get(metric, ""), bool(bad), context))
            if row["change_scale"] > 0:
                row["change_error_scaled"] = row["change_error"] / row["change_scale"]
        elif kind == "pair":
            row["n_frames_left_out"] = int(np.isnan(c.prediction).sum())
        rows.append(row)
        if kind == "mse":
            rows += [{**base, "sim": s, "mse": v, "n_sims": 1,
                      "n_frames": int((part["sim"] == s).sum()), "n_blown_up": int(b), "blown_up_sims": s if b else ""}
                     for s, v, b in zip(sims, figures[method], blown[method], strict=True)]
    return rows


def plausibility_row(metric: str, group: pd.DataFrame, frames: list[int] | None, blown: bool) -> dict:
    """A plausibility measure over the scored frames of every sim: the truth's and the prediction's largest value
    (overlaps, kinetic energy) or sum (particles outside the box); the kinetic energy also gets the article-style
    Acc against the truth. A blown-up rollout has no value, only its flag."""
    how = plausibility.AGGREGATE[metric]
    truth, prediction = group["truth"].to_numpy(np.float64), group["prediction"].to_numpy(np.float64)
    reduce = np.nanmax if how == "max" else np.nansum
    out = {"mean_truth": float(reduce(truth)) if np.isfinite(truth).any() else float("nan"),
           "mean_prediction": float("nan") if blown or not np.isfinite(prediction).any() else float(reduce(prediction)),
           "n_frames_left_out": int((~np.isfinite(truth)).sum())}
    if metric == "Kinetic energy" and not blown:
        curve = curve_accuracy(group["tau"].to_numpy(), truth, prediction, frames)
        out.update(acc_percent=curve.acc, acc_frames=frame_list(curve.frames),
                   acc_pooled_percent=accuracy(truth, prediction)[0])
    return out


def summarise(steps: pd.DataFrame, frames: list[int] | None = None, intervals: Intervals | None = None,
              units: dict[str, str] | None = None) -> pd.DataFrame:
    """metrics.csv rows of a per-step table (module docstring): per method and metric over all sims
    (``sim = all``), plus the rollout MSE per sim. ``frames``: the taus of the article-style Acc (every
    predicted frame when None); ``intervals``: the bootstrap (default: the config's); ``units``: units of metrics
    beside (or instead of) those the steps' scene registers (:func:`evaluation.metrics.units`): the ``unit``
    column, and what decides how a change error is scaled."""
    from evaluation.metrics import units as metric_units
    intervals = intervals or default_intervals()
    sims = list(dict.fromkeys(steps["sim"]))
    scene = str(steps["scene"].iloc[0]) if "scene" in steps and len(steps) else None
    context = {"frames": frames, "intervals": intervals, "draws": intervals.draws(len(sims)),
               "units": {**metric_units(scene), **(units or {})}}
    steps = steps if "member" in steps else steps.assign(member=0)
    rows = []
    for metric, group in steps.groupby("metric", sort=False):
        rows += metric_rows(str(metric), group, sims, context)
    order = list(dict.fromkeys(steps["metric"]))
    table = pd.DataFrame(rows).reindex(columns=COLUMNS)
    table["metric"] = pd.Categorical(table["metric"], categories=order, ordered=True)
    table = table.sort_values(["metric", "method"], kind="stable").reset_index(drop=True)
    table["metric"] = table["metric"].astype(str)
    return table
