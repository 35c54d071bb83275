"""The kinds of generated tables (docs/tables.md): each reads one results CSV and returns a markdown table.

A table named ``<subject>-<kind>`` (``slide-metrics``, ``slide_samer-card``) is kind ``<kind>`` of
``results/<subject>/``: every scene and public benchmark gets one without code of its own. A kind also names
its ``sources``, the files whose code computes its CSV's numbers (glob patterns relative to the folder that
holds the ``generators``, ``surrogate`` and ``evaluation`` packages; ``{subject}`` is the table's subject); a
stamp's code hash covers them, so ``graphdem tables --check`` flags the table after any of them changed. The code
that only lays the table out (this module) is not among them: a change of layout is rewritten by ``--write`` from
the same CSV.

Numbers are rounded as :data:`NUMBER` (3 significant digits), :data:`PERCENT` (Acc: one decimal) and
:data:`SCORE` (skill and errors in ensemble spreads: two decimals), a spread over seeds as :data:`SPREAD` (2
significant digits); an interval ``*_ci_low``/``*_ci_high`` of
the CSV follows its figure in the same rounding, ``0.58 [0.41, 0.77]``. This module imports nothing heavy at
load time: ``--check`` reads only :data:`KINDS`' names and sources.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pandas as pd

# How numbers are rounded in every generated table (Python format specs).
NUMBER, PERCENT, SCORE, SPREAD = ".3g", ".1f", ".2f", ".2g"
# What a cell says where the CSV has no number: a blown-up rollout, or a value that does not exist.
BLOWN_UP, UNDEFINED = "blown up", "undefined"

# The code behind each CSV (module docstring): the evaluation's, the performance stage's, the benchmark card's.
EVALUATION = ("evaluation/evaluate.py", "evaluation/summary.py", "evaluation/stored.py", "evaluation/metrics/*.py",
              "evaluation/baseline.py", "surrogate/rollout.py")
PERFORMANCE = ("evaluation/performance.py", "surrogate/batched.py", "surrogate/runtime.py", "generators/engine.py",
               *EVALUATION)
CARD = ("evaluation/card.py", "evaluation/seeds.py", "surrogate/ensemble.py", *EVALUATION)

# How the tables name a method of the CSVs; a method not listed is shown by its own name.
METHODS = {"graphdem": "Graph-DEM", "constant_velocity": "constant velocity", "dem_ensemble": "DEM ensemble",
           "dem_ensemble_mean": "DEM ensemble mean", "seed_ensemble": "seed ensemble", "gns": "GNS"}


@dataclass(frozen=True)
class Quantity:
    """A figure of metrics.csv the metrics table can show: its column, its row's label (``{metric}`` is the
    metric's name), the format spec and unit of its number, and the prefix of its interval columns."""

    column: str
    label: str
    spec: str = NUMBER
    unit: str = ""
    interval: str | None = None

    def cell(self, row: dict | None) -> str:
        """The figure of one method's row (None: the method has no row for this metric), with its interval."""
        if row is None:
            return ""
        value = row.get(self.column)
        if not finite(value):
            return BLOWN_UP if finite(row.get("n_blown_up")) and row["n_blown_up"] > 0 else UNDEFINED
        text = f"{float(value):{self.spec}}{self.unit}"
        prefix = self.interval or self.column
        low, high = row.get(f"{prefix}_ci_low"), row.get(f"{prefix}_ci_high")
        if finite(low) and finite(high):
            text += f" [{float(low):{self.spec}}, {float(high):{self.spec}}]"
        return text


# Each metric's first row: the first of these the CSV has a number for (the rollout MSE, the article's Acc of a
# metric with a truth of its own, else the mean: Dis, the plausibility measures).
PRIMARY = (Quantity("mse", "{metric} (m²)"), Quantity("acc_percent", "{metric}: Acc", PERCENT, " %", "acc"),
           Quantity("mean_prediction", "{metric}"))
# Figures the evaluation writes for some metrics: a row of their own where the CSV has a number, else none.
EXTRA = (Quantity("change_error", "{metric}: change error"), Quantity("skill", "{metric}: skill", SCORE),
         Quantity("error_in_spreads", "{metric}: error in ensemble spreads", SCORE))


@dataclass(frozen=True)
class Kind:
    """A kind of table: its CSV (relative to the results folder; ``{subject}`` is the table name's first part),
    the columns it cannot do without, the producing sources and the function from the CSV to the table."""

    name: str
    csv: str
    columns: tuple[str, ...]
    sources: tuple[str, ...]
    render: Callable[[pd.DataFrame], str]


def finite(value: object) -> bool:
    """Whether ``value`` is a finite number (an empty CSV cell reads as NaN)."""
    try:
        return math.isfinite(float(value))          # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False


def markdown(header: list[str], rows: list[list[str]]) -> str:
    """A markdown table; a ``|`` inside a cell is escaped."""
    lines = [header, ["---"] * len(header), *rows]
    return "\n".join("| " + " | ".join(str(c).replace("|", r"\|") for c in line) + " |" for line in lines)


def _methods(names: list[str], first: tuple[str, ...]) -> list[str]:
    """The methods in the order ``first`` (those present), then the others as they come."""
    names = list(dict.fromkeys(names))
    return [m for m in first if m in names] + [m for m in names if m not in first]


def by_metric(overall: pd.DataFrame) -> Iterator[tuple[object, bool, str, dict[str, dict]]]:
    """(K, whether there are several K, metric, method -> row) for every metric of every protocol K of a
    metrics.csv's ``sim = all`` rows, in the CSV's order."""
    ks = list(dict.fromkeys(overall["history"])) if "history" in overall else [None]
    for k in ks:
        here = overall if k is None else overall[overall["history"] == k]
        for metric in dict.fromkeys(here["metric"]):
            yield k, len(ks) > 1, metric, {r["method"]: r for r in here[here["metric"] == metric].to_dict("records")}


def metrics(table: pd.DataFrame) -> str:
    """results/<scene>/metrics.csv: a row per metric (its primary figure, then each :data:`EXTRA` figure it has)
    and protocol K where there are several; columns: the DEM truth's mean, then one per method."""
    from evaluation.evaluate import BASELINE, CAPPED, DROPPED, ENSEMBLE, MODEL, SECONDS
    overall = table[(table["sim"] == "all") & ~table["metric"].isin([SECONDS, CAPPED, DROPPED])]
    methods = _methods(list(overall["method"]), (MODEL, BASELINE, ENSEMBLE))
    rows = []
    for k, several, metric, by_method in by_metric(overall):
        has = [q for q in (*PRIMARY, *EXTRA) if any(finite(r.get(q.column)) for r in by_method.values())]
        shown = [next((q for q in PRIMARY if q in has), PRIMARY[-1]), *(q for q in EXTRA if q in has)]
        truth = next((r["mean_truth"] for r in by_method.values() if finite(r.get("mean_truth"))), None)
        for i, quantity in enumerate(shown):
            label = quantity.label.format(metric=metric) + (f" (K = {k})" if several else "")
            truth_cell = f"{float(truth):{NUMBER}}" if i == 0 and truth is not None else ""
            rows.append([label, truth_cell, *(quantity.cell(by_method.get(m)) for m in methods)])
    return markdown(["metric", "DEM truth (mean)", *(METHODS.get(m, m) for m in methods)], rows)


# The summary's figures per metric: its error (the MSE, the change error, or the compared value such as Dis).
ERROR = (Quantity("mse", "", NUMBER), Quantity("change_error", "", NUMBER), Quantity("mean_prediction", "", NUMBER))
SKILL = Quantity("skill", "", SCORE)
SPREADS = Quantity("error_in_spreads", "", SCORE)
ACC = Quantity("acc_percent", "", PERCENT, " %", "acc")


def error_of(row: dict) -> Quantity:
    """A summary row's error figure: the rollout MSE, a scene metric's change error (its row names the change's
    scale) or a compared metric's value (Dis)."""
    if finite(row.get("mse")):
        return ERROR[0]
    return ERROR[1] if isinstance(row.get("change_scale_kind"), str) else ERROR[2]


def summary(table: pd.DataFrame) -> str:
    """results/<scene>/metrics.csv in brief (the README's table): a row per metric that has an error figure (the
    rollout MSE, each scene metric's change error, each compared metric), named with its unit (the CSV's ``unit``
    column), with Graph-DEM's error, the DEM
    ensemble members' error, Graph-DEM's skill against constant velocity, its error in ensemble spreads, and
    the article's Acc of Graph-DEM and of constant velocity; intervals where the CSV has them."""
    from evaluation.evaluate import BASELINE, CAPPED, DROPPED, ENSEMBLE, MODEL, SECONDS
    from evaluation.metrics import plausibility, shown, units
    skipped = {SECONDS, CAPPED, DROPPED, *plausibility.AGGREGATE}       # timings; plausibility: the metrics table
    overall = table[table["sim"] == "all"]
    registered = units()                          # for a CSV written before it had a unit column
    rows = []
    for k, several, metric, by_method in by_metric(overall):
        model = by_method.get(MODEL)
        if model is None or metric in skipped:
            continue
        error = error_of(model)
        unit = model["unit"] if isinstance(model.get("unit"), str) else registered.get(metric, "")
        label = f"{metric} ({shown(unit) or '-'})" + (f", K = {k}" if several else "")
        rows.append([label, error.cell(model), error.cell(by_method.get(ENSEMBLE)), SKILL.cell(model),
                     SPREADS.cell(model) if finite(model.get("error_in_spreads")) else "",
                     ACC.cell(model) if finite(model.get("acc_percent")) else "",
                     ACC.cell(by_method.get(BASELINE)) if finite(model.get("acc_percent")) else ""])
    return markdown(["metric (unit)", "Graph-DEM error", "DEM member error", "skill vs constant velocity",
                     "in DEM ensemble spreads", "Acc, article (Graph-DEM)", "Acc, article (constant velocity)"],
                    rows)


def speed(table: pd.DataFrame) -> str:
    """results/<scene>/performance.csv: a row per contender (the settling row left out): its kind, milliseconds per
    predicted frame, rollout MSE and speed-up over the DEM reference; the headline contender marked (main)."""
    rows = []
    for row in table[table["kind"] != "dem_settling"].to_dict("records"):
        missing = BLOWN_UP if str(row.get("stable")) == "False" else "n/a"      # n/a: timed only, never scored

        def number(value: object, scale: float = 1.0, unit: str = "", missing: str = missing) -> str:
            """A number of the row, scaled and rounded, with its unit; ``missing`` where there is none."""
            return f"{scale * float(value):{NUMBER}}{unit}" if finite(value) else missing

        name = row["contender"] + (" (main)" if str(row.get("main")) == "True" else "")
        rows.append([name, str(row["kind"]), number(row["seconds_per_frame"], 1000.0), number(row["mse"]),
                     number(row["speedup_vs_reference"], unit="x")])
    return markdown(["contender", "kind", "ms per frame", "rollout MSE (m²)", "speed-up over the DEM reference"],
                    rows)


def sim_map(table: pd.DataFrame) -> str:
    """results/<scene>/performance_map.csv: a row per comparison and test sim: the DEM contender, its sub-steps and
    milliseconds per frame on the sim, the surrogate's, the speed-up, the break-even sub-steps and whether it pays."""
    rows = [[str(r["match"]), f"{r['dem_contender']}", str(r["sim"]), f"{int(r['particles'])} ({int(r['moving'])})",
             f"{float(r['dem_steps_per_frame']):.0f}", f"{float(r['dem_ms_per_frame']):{NUMBER}}",
             f"{float(r['surrogate_ms_per_frame']):{NUMBER}}", f"{float(r['speedup']):{NUMBER}}x",
             f"{float(r['break_even_steps']):.0f}", "yes" if str(r["pays"]) == "True" else "no"]
            for r in table.to_dict("records")]
    return markdown(["DEM compared", "DEM contender", "sim", "particles (moving)", "DEM sub-steps per frame",
                     "DEM ms per frame", "Graph-DEM ms per frame", "speed-up", "break-even sub-steps", "pays"], rows)


def pays(table: pd.DataFrame) -> str:
    """results/performance_pays.csv: a row per scene: does the surrogate pay against the closest DEM comparison its
    test sims have, by how much (the median speed-up over them and its range), and why (the DEM's sub-steps per frame
    against the break-even)."""
    rows = []
    for r in table.to_dict("records"):
        why = (f"{float(r['dem_steps_per_frame']):.0f} DEM sub-steps per frame ({float(r['dem_steps_min']):.0f}-"
               f"{float(r['dem_steps_max']):.0f}) against a break-even of {float(r['break_even_steps']):.0f}")
        rows.append([str(r["scene"]), str(r["verdict"]),
                     f"{float(r['speedup']):{NUMBER}}x [{float(r['speedup_min']):{NUMBER}}, "
                     f"{float(r['speedup_max']):{NUMBER}}]", f"{r['dem_contender']} ({r['match']})",
                     f"{float(r['surrogate_ms_per_frame']):{NUMBER}} / {float(r['dem_ms_per_frame']):{NUMBER}}",
                     why, (f"{float(r['speedup_vs_fastest']):{NUMBER}}x ({r['fastest_contender']})"
                           if finite(r.get("speedup_vs_fastest")) else ""), f"{int(r['sims'])}"])
    return markdown(["scene", "surrogate", "speed-up (median [range] over test sims)", "against the DEM",
                     "ms per frame, surrogate / DEM", "why", "against the fastest DEM, any error", "test sims"], rows)


def card(table: pd.DataFrame) -> str:
    """results/<benchmark>/card.csv: a row per quantity and protocol K, a column per method (measured, then the
    article's); a measured cell is the mean over the seeds ± their standard deviation (blow-ups: the total)."""
    from evaluation.card import ARTICLE, QUANTITIES
    columns = list(dict.fromkeys(zip(table["source"], table["method"], strict=True)))
    columns.sort(key=lambda c: c[0] == ARTICLE)
    keys = table[["quantity", "history"]].drop_duplicates().to_records(index=False).tolist()
    keys.sort(key=lambda q: (list(QUANTITIES).index(q[0]) if q[0] in QUANTITIES else len(QUANTITIES),
                             float(q[1]) if finite(q[1]) else math.inf))
    rows = []
    for quantity, k in keys:
        here = table[(table["quantity"] == quantity) & (table["history"].astype(str) == str(k))]
        cells = {(r["source"], r["method"]): _card_cell(r) for r in here.to_dict("records")}
        label = f"{QUANTITIES.get(quantity, (None, quantity))[1]} ({here['unit'].iloc[0]})"
        rows.append([label, f"{int(float(k))}" if finite(k) else "all", *(cells.get(c, "") for c in columns)])
    heads = [("article: " if s == ARTICLE else "") + METHODS.get(m, m) for s, m in columns]
    return markdown(["quantity", "K", *heads], rows)


def _card_cell(row: dict) -> str:
    """A card.csv row's cell: the total of blow-ups, else the mean, ± the standard deviation where there is one."""
    blown = row["quantity"] == "blown_up" and finite(row.get("total"))
    value = row["total"] if blown else row["mean"]
    text = f"{float(value):{NUMBER}}" if finite(value) else UNDEFINED
    if not blown and finite(row.get("std")):
        text += f" ± {float(row['std']):{SPREAD}}"
    return text


def runout(table: pd.DataFrame) -> str:
    """results/<scene>/physics.csv of a runout-law check: a row per fit (all sims, then per friction): the column
    width (mean grain diameters), the sims at rest that it fits, the linear prefactor, the power law, the final
    height's exponent and the longest rest time of its sims (in sqrt(H0 / g) of each settled column)."""
    sims, fits = table[table["sim"] != "fit"], table[table["sim"] == "fit"]
    rows = []
    for fit in fits.to_dict("records"):
        group = str(fit["friction"])
        mine = sims if group == "all" else sims[[f"{float(f):g}" == group for f in sims["friction"]]]
        at_rest = mine["at_rest"].astype(str).str.lower() == "true"
        power = (f"{float(fit['power_prefactor']):{NUMBER}} a^{float(fit['power_exponent']):.2f}"
                 if finite(fit["power_prefactor"]) else UNDEFINED)
        lam = f"{float(fit['linear_prefactor']):{NUMBER}} a" if finite(fit["linear_prefactor"]) else UNDEFINED
        beta = f"{float(fit['height_exponent']):.2f}" if finite(fit["height_exponent"]) else UNDEFINED
        longest = mine.loc[at_rest, "rest_time_scaled"].astype(float)
        widths = sorted({f"{float(w):.2g}" for w in mine["column_diameters"]})
        rows.append([group, ", ".join(widths), f"{int(at_rest.sum())} of {len(mine)}",
                     f"{lam} ({int(fit['n_small'])} sims)", f"{power} ({int(fit['n_large'])} sims)", beta,
                     f"{longest.max():.1f}" if len(longest) else UNDEFINED])
    return markdown(["friction", "column width (mean diameters)", "sims at rest (fitted)",
                     "small a: lambda a (a < 1.8)", "large a: c a^alpha (a > 2.8)", "H_inf/L0 exponent (a > 1.15)",
                     "longest rest time (sqrt(H0/g))"], rows)


KINDS = {kind.name: kind for kind in (
    Kind("metrics", "{subject}/metrics.csv", ("method", "metric", "sim"), EVALUATION, metrics),
    Kind("summary", "{subject}/metrics.csv", ("method", "metric", "sim"), EVALUATION, summary),
    Kind("speed", "{subject}/performance.csv", ("contender", "kind", "seconds_per_frame", "mse",
                                              "speedup_vs_reference"), PERFORMANCE, speed),
    Kind("map", "{subject}/performance_map.csv", ("sim", "match", "dem_contender", "dem_steps_per_frame", "speedup",
                                                   "break_even_steps", "pays"),
         ("evaluation/performance_map.py", *PERFORMANCE), sim_map),
    Kind("pays", "performance_pays.csv", ("scene", "verdict", "speedup", "dem_contender", "break_even_steps"),
         ("evaluation/performance_map.py", "evaluation/commands/performance.py", *PERFORMANCE), pays),
    Kind("card", "{subject}/card.csv", ("source", "method", "history", "quantity", "unit", "mean", "std"), CARD,
         card),
    Kind("runout", "{subject}/physics.csv", ("sim", "friction", "column_diameters", "linear_prefactor",
                                             "power_prefactor", "power_exponent", "height_exponent", "at_rest",
                                             "rest_time_scaled"),
         ("generators/scenes/{subject}.py", "generators/contact.py", "generators/engine.py"), runout),
)}
