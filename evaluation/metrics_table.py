"""metrics.csv as an HTML table for the Snakemake report, with every empty cell of the CSV named.

metrics.csv keeps NaN (an empty cell) wherever a value does not exist, and the CSV stays as it is. The
table tells the two kinds apart:

- ``n/a``: the column does not apply to the row's metric (no Acc, truth or mean prediction for the rollout MSE,
  whose figure is its MSE; no Acc or truth for a metric that compares the prediction with the truth, such as
  the slide's Dis; no MSE for a scene metric; only the mean for the rollout timing and the neighbour cap's
  counts);
- ``undefined``: the column applies but has no value, with the reason: a blown-up rollout (named), or a
  quantity whose DEM truth is zero or undefined in every scored frame (e.g. the meteorite's crater depth
  before any ground disc moved), or a rollout without a recorded timing.
"""

from __future__ import annotations

import html
import math
from pathlib import Path

import pandas as pd

from evaluation.tables import read_csv
from generators.atomic import atomic_path

MSE = "rollout MSE"
SECONDS = "seconds per frame"
CAP_COUNTS = {"capped receivers per frame", "dropped edges per frame"}     # a model with a neighbour cap
# plausibility measures without an Acc (the kinetic energy has one: a metric with a truth)
PLAUSIBILITY = {"Max overlap", "P99 overlap", "Outside box", "Through wall"}

# The value columns shown, with their headings.
COLUMNS = {"acc_percent": "Acc (%), article", "acc_frames": "Acc frames (tau)",
           "acc_pooled_percent": "Acc (%), pooled", "mse": "MSE (m²)", "change_error": "change error",
           "change_error_scaled": "change error, scaled", "skill": "skill vs constant velocity",
           "error_in_spreads": "error in ensemble spreads", "vs_members": "error / members' error",
           "mean_truth": "mean truth", "mean_prediction": "mean prediction", "n_sims": "sims", "n_frames": "frames",
           "n_frames_left_out": "frames left out", "n_blown_up": "blown up"}
COUNTS = ("n_sims", "n_frames", "n_frames_left_out", "n_blown_up")
# figures with a bootstrap interval (evaluation/summary.py): the column of its bounds' prefix
INTERVALS = {"acc_percent": "acc", "mse": "mse", "change_error": "change_error", "skill": "skill",
             "mean_prediction": "mean_prediction"}
# figures that exist only beside a reference: skill beside constant velocity, the rest beside a DEM ensemble
COMPARED = ("skill", "error_in_spreads", "vs_members")
# a table without the DEM ensemble (user data, the public benchmarks: no engine config to rerun their sims) shows
# the ensemble's figures as n/a
ENSEMBLE_METHOD, ENSEMBLE_FIGURES = "dem_ensemble", ("error_in_spreads", "vs_members")
NO_ENSEMBLE = ("no DEM ensemble in this evaluation: only a scene's test sims are rerun by their engine (user data "
               "and the public benchmarks have no engine config)")

# The columns that apply to each kind of row; every other value column is n/a for it.
APPLIES = {
    "mse": {"mse", "skill", "error_in_spreads", "vs_members", "n_sims", "n_frames", "n_blown_up"},
    "seconds": {"mean_prediction", "n_sims"},
    "cap": {"mean_prediction", "n_sims"},
    "truth": {"acc_percent", "acc_frames", "acc_pooled_percent", "change_error", "change_error_scaled", "skill",
              "error_in_spreads", "vs_members", "mean_truth", "mean_prediction", "n_sims", "n_frames",
              "n_frames_left_out", "n_blown_up"},
    "pair": {"skill", "vs_members", "mean_prediction", "n_sims", "n_frames", "n_frames_left_out", "n_blown_up"},
    "plausibility": {"mean_truth", "mean_prediction", "n_sims", "n_frames", "n_frames_left_out", "n_blown_up"},
}
NOT_APPLICABLE = {
    "mse": "the rollout MSE is its own error measure (the MSE column): no Acc, no truth or mean value, no frames "
           "left out",
    "seconds": "the rollout wall time per predicted frame: a mean over sims only",
    "cap": "what the neighbour cap cut per predicted frame of the rollout: a mean over sims only",
    "truth": "a scene metric has Acc against its truth, not an MSE",
    "pair": "this metric compares the prediction with the truth frame by frame: no truth value of its own, "
            "so no Acc and no MSE",
    "plausibility": "a plausibility measure: the truth's and the prediction's largest value over the scored "
                    "frames (particles outside the box: their sum), no Acc",
}

STYLE = """
body { font-family: sans-serif; font-size: 13px; margin: 12px; color: #1e293b; }
h1 { font-size: 16px; margin: 0 0 4px; } h2 { font-size: 14px; margin: 16px 0 4px; }
p.provenance { color: #475569; margin: 0 0 8px; }
table { border-collapse: collapse; }
th, td { border: 1px solid #cbd5e1; padding: 3px 6px; text-align: right; vertical-align: top; }
th { background: #e2e8f0; } td.text { text-align: left; }
span.na { color: #94a3b8; font-style: italic; }
span.ci { color: #475569; font-size: 11px; }
span.undefined { color: #b45309; font-weight: bold; }
span.why, td.why { color: #b45309; font-size: 11px; }
ul.legend { color: #475569; padding-left: 18px; }
"""


def shown(table: pd.DataFrame) -> list[str]:
    """The value columns of :data:`COLUMNS` that the table has (a table written before a figure existed shows
    none of it)."""
    return [c for c in COLUMNS if c in table.columns]


def _kind(row: pd.Series, metric_names: dict[str, set[str]]) -> str:
    metric = row["metric"]
    if metric == MSE:
        return "mse"
    if metric == SECONDS:
        return "seconds"
    if metric in CAP_COUNTS:
        return "cap"
    if metric in PLAUSIBILITY:
        return "plausibility"
    if metric in metric_names["truth"]:
        return "truth"
    if metric in metric_names["pair"]:
        return "pair"
    # a metric of no registered scene: it has a truth where the CSV has one
    return "truth" if pd.notna(row.get("mean_truth")) or pd.notna(row.get("acc_percent")) else "pair"


def _scene_metrics(scene: str) -> dict[str, set[str]]:
    from evaluation.metrics import of_scene
    cls = of_scene(scene)
    if cls is None:
        return {"truth": set(), "pair": set()}
    return {"truth": set(cls.names), "pair": set(cls.pair_names)}


def _is_nan(value) -> bool:
    return value is None or bool(pd.isna(value))


def why_undefined(row: pd.Series, kind: str, column: str) -> str:
    """Why ``column``, which applies to ``row``, is NaN in metrics.csv."""
    blown = 0 if _is_nan(row.get("n_blown_up")) else int(row["n_blown_up"])
    if blown:
        sims = str(row.get("blown_up_sims") or "").strip()
        return f"{blown} rollout(s) blew up" + (f": {sims}" if sims else "")
    frames, left_out = row.get("n_frames"), row.get("n_frames_left_out")
    every = not _is_nan(frames) and not _is_nan(left_out) and int(left_out) >= int(frames) > 0
    truthless = _is_nan(row.get("mean_truth"))
    if kind == "truth" and column in ("acc_percent", "acc_pooled_percent", "mean_truth") and truthless:
        return "the DEM truth is zero or undefined in every scored frame"
    if column == "mean_prediction" and every:
        return f"undefined in all {int(frames)} scored frames"
    if column == "skill":
        return "no constant-velocity figure to compare with"
    if column in COMPARED:
        return "no DEM ensemble scored beside it"
    if kind == "seconds":
        return "no rollout timing recorded"
    if kind == "cap":
        return "the rollouts read did not record the neighbour cap's counts"
    return "not defined for these sims"


def _number(column: str, value) -> str:
    if column == "acc_frames":
        return html.escape(str(value))
    if column in COUNTS:
        return str(int(value))
    if isinstance(value, float) and math.isinf(value):
        return "+inf" if value > 0 else "-inf"
    return f"{float(value):.4g}"


def cell(row: pd.Series, column: str, kind: str, ensemble: bool = True) -> tuple[str, str | None]:
    """One value cell (the number, n/a or undefined) and, for undefined, why; without an ``ensemble`` in the table,
    the DEM ensemble's figures are n/a."""
    value = row.get(column)
    if not ensemble and column in ENSEMBLE_FIGURES and _is_nan(value):
        return f'<td><span class="na" title="{html.escape(NO_ENSEMBLE)}">n/a</span></td>', None
    if column not in APPLIES[kind] and _is_nan(value):
        return f'<td><span class="na" title="{html.escape(NOT_APPLICABLE[kind])}">n/a</span></td>', None
    if _is_nan(value):
        why = why_undefined(row, kind, column)
        return f'<td><span class="undefined" title="{html.escape(why)}">undefined</span></td>', why
    text = _number(column, value)
    bounds = [row.get(f"{INTERVALS[column]}_ci_{side}") for side in ("low", "high")] if column in INTERVALS else []
    if bounds and not any(_is_nan(b) for b in bounds):
        text += f' <span class="ci">[{_number(column, bounds[0])}, {_number(column, bounds[1])}]</span>'
    if column == "n_blown_up" and int(value) and str(row.get("blown_up_sims") or "").strip():
        text += f' <span class="why">{html.escape(str(row["blown_up_sims"]))}</span>'
    return f"<td>{text}</td>", None


def _rows(table: pd.DataFrame, units: dict[str, str], metric_names: dict[str, set[str]]) -> str:
    from evaluation.metrics import shown as shown_unit
    out = []
    ensemble = bool((table["method"] == ENSEMBLE_METHOD).any())
    for _, row in table.iterrows():
        kind = _kind(row, metric_names)
        unit = units.get(row["metric"], "") if _is_nan(row.get("unit")) else str(row["unit"])
        unit = "" if kind == "mse" else shown_unit(unit)
        label = html.escape(str(row["metric"]) + (f" ({unit})" if unit else ""))
        cells = [f'<td class="text">{html.escape(str(row["method"]))}</td>', f'<td class="text">{label}</td>',
                 f'<td class="text">{html.escape(str(row["sim"]))}</td>']
        values = [cell(row, column, kind, ensemble) for column in shown(table)]
        whys = list(dict.fromkeys(why for _, why in values if why))
        cells += [html_cell for html_cell, _ in values]
        cells.append(f'<td class="text why">{html.escape("; ".join(whys))}</td>')
        out.append("<tr>" + "".join(cells) + "</tr>")
    return "\n".join(out)


def _table(table: pd.DataFrame, units: dict[str, str], metric_names: dict[str, set[str]]) -> str:
    head = "".join(f"<th>{h}</th>" for h in ("method", "metric", "sim", *(COLUMNS[c] for c in shown(table)),
                                              "why undefined"))
    return f"<table>\n<tr>{head}</tr>\n{_rows(table, units, metric_names)}\n</table>"


def to_html(table: pd.DataFrame, title: str) -> str:
    """The HTML page of a metrics.csv table (one section per protocol K where there are several); each metric
    named with its unit (the CSV's ``unit`` column, else the scene's registered unit)."""
    from evaluation.metrics import units as metric_units
    scene = str(table["scene"].iloc[0]) if len(table) else ""
    units = metric_units(scene or None)
    names = _scene_metrics(scene)
    parts = [f"<h1>{html.escape(title)}</h1>"]
    groups = list(table.groupby("history", sort=False)) if "history" in table.columns else [(None, table)]
    for k, rows in groups:
        first = rows.iloc[0]
        facts = [f"scene {scene}"]
        if "split" in rows.columns:
            facts.append(f"split {first['split']}")
        if k is not None:
            facts.append(f"K = {int(k)} history frames given")
        for column, name in (("checkpoint_sha", "checkpoint"), ("code_version", "code")):
            if column in rows.columns and not _is_nan(first[column]):
                facts.append(f"{name} {first[column]}")
        note = "" if "split_note" not in rows.columns or _is_nan(first["split_note"]) else str(first["split_note"])
        if len(groups) > 1:
            parts.append(f"<h2>K = {int(k)}</h2>")
        parts.append(f'<p class="provenance">{html.escape(", ".join(facts))}'
                     + (f"<br>{html.escape(note)}" if note else "") + "</p>")
        overall, per_sim = rows[rows["sim"] == "all"], rows[rows["sim"] != "all"]
        parts.append("<h2>Mean over the sims (sim = all)</h2>")
        parts.append(_table(overall, units, names))
        if len(per_sim):
            parts.append("<h2>Per sim</h2>")
            parts.append(_table(per_sim, units, names))
    parts.append(
        '<ul class="legend">'
        '<li><span class="na">n/a</span>: the column does not apply to the metric (hover for why); '
        "an empty cell in metrics.csv.</li>"
        '<li><span class="undefined">undefined</span>: the column applies but has no value, for the reason '
        "in the row's last column; an empty cell (NaN) in metrics.csv, never a number.</li>"
        '<li><span class="ci">[low, high]</span>: the bootstrap interval over the sims (metrics.csv\'s '
        "*_ci_low and *_ci_high).</li></ul>")
    return ("<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{STYLE}</style></head>\n<body>\n"
            + "\n".join(parts) + "\n</body></html>\n")


def write(metrics_csv: str | Path, out: str | Path, title: str) -> Path:
    """Render ``metrics_csv`` (read back as written, so the table shows exactly the CSV) to ``out``."""
    table = read_csv(metrics_csv, keep_default_na=True, dtype={"acc_frames": str})   # "5" is a tau list, not 5.0
    out = Path(out)
    with atomic_path(out) as tmp:
        tmp.write_text(to_html(table, title), encoding="utf-8")
    return out
