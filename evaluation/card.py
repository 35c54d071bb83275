"""The benchmark card of a public benchmark (docs/benchmarks.md, "Benchmark card"): Graph-DEM and constant
velocity under every protocol K, over the models trained with different seeds (the seeds stage), beside the
article's published figures.

Every quantity is first taken per seed (one model, scored by the evaluate stage on the same sims), then
summarised over the seeds: the mean, the sample standard deviation (ddof 1; undefined for one seed), the
smallest and largest value, the number of seeds and each seed's value (``values``, ``seed:value``). NaN is
never skipped: a seed whose rollout blew up on a sim has a NaN rollout MSE, which makes the mean over the
seeds NaN too.

Quantities (``quantity``, ``unit``), per method and protocol K unless said otherwise:

- ``rollout_mse`` (m^2): the evaluate stage's rollout MSE (metrics.csv, ``sim = all``): the squared distance
  between predicted and true positions, summed over the axes, averaged over the moving particles and the
  predicted frames of a sim, then over the sims.
- ``mse_first_frame``, ``mse_last_frame`` (m^2): the same squared distance at the first (tau = 1) and at the
  last predicted frame only, averaged over the moving particles and over the sims (metrics_per_step.csv's
  per-sim rows).
- ``rmse_diameters`` (diameters): the error in particle diameters, ``sqrt(rollout_mse) / d``, where ``d`` is
  the mean diameter of the moving (non-kinematic) particles: twice the dataset stage's mean radius
  (stats.json, ``property_stats.radius.mean``, over the moving particles of the train sims).
- ``blown_up`` (rollouts): the rollouts that blew up (metrics.csv's ``n_blown_up`` of the rollout MSE), per
  seed; ``total`` counts them over all seeds.
- ``rollout_ms_per_frame`` (ms, Graph-DEM): the rollout's wall time per predicted frame, a mean over the sims
  (metrics.csv's ``seconds per frame``).
- ``train_seconds`` (s, Graph-DEM, per model, no K): the training wall time, history.csv's ``seconds`` of
  the last epoch (training and validation, summed over the runs of a resumed job).
- ``train_cost`` (core-hours or GPU-hours, Graph-DEM, per model, no K): each epoch's wall time times what it
  ran on: ``threads x processes`` CPU cores on the CPU, ``processes`` GPUs on a GPU (history.csv's columns
  of those names), summed over the epochs, in hours.

The article's figures (the config's ``B.article``) are rows of ``source = article``: their rollout MSE and,
with the same ``d``, its ``rmse_diameters``.

With two or more seeds the card also scores their **seed ensemble** (method ``seed_ensemble``): the seeds'
models as one simulator that integrates the mean of their predicted accelerations every step
(:mod:`surrogate.ensemble`), evaluated once on the same sims. Its rows hold that one evaluation (``mean``; no
spread: ``n_seeds`` is the number of models in it), its ``train_seconds`` and ``train_cost`` are the sums over
its models (an ensemble costs every model it averages) and its rollout time is N forward passes per frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from evaluation.evaluate import BASELINE, MODEL, MSE, SECONDS
from evaluation.seeds import summary

# quantity -> (unit, what the card's table calls it); train_cost's unit is the hardware's (core- or GPU-hours)
QUANTITIES = {
    "rollout_mse": ("m^2", "rollout MSE"),
    "mse_first_frame": ("m^2", "MSE at the first predicted frame"),
    "mse_last_frame": ("m^2", "MSE at the last predicted frame"),
    "rmse_diameters": ("diameters", "RMSE in mean particle diameters"),
    "blown_up": ("rollouts", "blown up, over all seeds"),
    "rollout_ms_per_frame": ("ms", "rollout wall time per predicted frame"),
    "train_seconds": ("s", "training wall time per model"),
    "train_cost": (None, "training cost per model"),
}
CORE_HOURS, GPU_HOURS = "core-hours", "GPU-hours"
MEASURED, ARTICLE = "measured", "article"
NOT_APPLICABLE = ""          # written as an empty cell; an undefined number is written NaN
HARDWARE_COLUMNS = ("threads", "processes", "device", "device_name")
COLUMNS = ("benchmark", "source", "method", "history", "n_predicted", "split", "quantity", "unit", "mean", "std",
           "min", "max", "total", "n_seeds", "n_sims", "values")
ENSEMBLE = "seed_ensemble"    # the method name of the seeds' models averaged at inference
LABELS = {MODEL: "Graph-DEM", BASELINE: "constant velocity", "gns": "GNS",           # how the card.md names a method
          ENSEMBLE: "seed ensemble"}


@dataclass(frozen=True)
class Hardware:
    """Where a training epoch ran: ``device`` cpu or cuda:N, its name, torch threads per process, processes."""

    device: str
    device_name: str
    threads: int
    processes: int

    @property
    def on_gpu(self) -> bool:
        return self.device.startswith("cuda")

    @property
    def units(self) -> int:
        """The cores (CPU) or GPUs (GPU) the epoch held."""
        return self.processes if self.on_gpu else self.threads * self.processes

    def describe(self) -> str:
        if self.on_gpu:
            return f"{self.processes} x GPU ({self.device_name})"
        return f"CPU ({self.device_name}), {self.threads} torch thread(s) x {self.processes} process(es)"


@dataclass(frozen=True)
class Training:
    """A model's training cost: wall ``seconds``, ``hours`` of cores or GPUs (``unit``), the hardware its epochs
    ran on, and whether history.csv recorded it (``recorded``) or the fallback was assumed."""

    seconds: float
    hours: float
    unit: str
    hardware: tuple[Hardware, ...]
    recorded: bool


def mean_diameter(stats: dict) -> float:
    """The mean diameter of the moving particles: twice stats.json's mean radius (moving train particles)."""
    radius = stats.get("property_stats", {}).get("radius")
    if radius is None:
        raise ValueError("stats.json has no property_stats.radius: rebuild the dataset stage (graphdem dataset) "
                         "to get the moving particles' mean radius")
    if radius.get("log"):
        raise ValueError("stats.json normalises the radius as ln(radius): its mean is not the mean radius the "
                         "card's diameters need")
    diameter = 2.0 * float(radius["mean"])
    if not (math.isfinite(diameter) and diameter > 0):
        raise ValueError(f"stats.json's mean radius {radius['mean']!r} is not a positive number")
    return diameter


def _recorded(row: dict) -> bool:
    return all(c in row and pd.notna(row[c]) and row[c] != "" for c in HARDWARE_COLUMNS)


def records_hardware(history: pd.DataFrame) -> bool:
    """Whether every epoch of a history.csv says where it ran (written since it has those columns)."""
    return all(_recorded(row) for row in history.to_dict("records"))


def training(history: pd.DataFrame, fallback: Hardware | None = None) -> Training:
    """The training cost of one model from its history.csv: each epoch's wall time (``seconds`` is cumulative)
    times the cores or GPUs it ran on. Epochs that do not record their hardware (a history.csv written before
    it had those columns) take ``fallback``; without one they are refused."""
    if history.empty or "seconds" not in history.columns:
        raise ValueError(f"history.csv needs at least one epoch and the column 'seconds'; it has "
                         f"{len(history)} rows and the columns {list(history.columns)}")
    seconds = history["seconds"].astype(float).to_numpy()
    steps = np.diff(seconds, prepend=0.0)
    if not np.isfinite(seconds).all() or (steps < 0).any():
        raise ValueError(f"history.csv's 'seconds' must be the cumulative training time (finite, never "
                         f"decreasing); got {seconds.tolist()}")
    kinds, unrecorded = [], []
    for i, row in enumerate(history.to_dict("records")):
        if _recorded(row):
            kinds.append(Hardware(str(row["device"]), str(row["device_name"]), int(row["threads"]),
                                  int(row["processes"])))
        elif fallback is not None:
            kinds.append(fallback)
            unrecorded.append(i + 1)
        else:
            raise ValueError(f"history.csv epoch {row.get('epoch', i + 1)} does not record where it ran (columns "
                             f"{', '.join(HARDWARE_COLUMNS)}); give the threads and device it trained on")
    if len({h.on_gpu for h in kinds}) > 1:
        raise ValueError("history.csv: some epochs ran on a GPU and some on the CPU; their cost has no one unit "
                         f"({', '.join(sorted({h.describe() for h in kinds}))})")
    hours = float(sum(s * h.units for s, h in zip(steps, kinds, strict=True)) / 3600.0)
    return Training(seconds=float(seconds[-1]), hours=hours, unit=GPU_HOURS if kinds[0].on_gpu else CORE_HOURS,
                    hardware=tuple(dict.fromkeys(kinds)), recorded=not unrecorded)


def _needs(table: pd.DataFrame, columns: tuple[str, ...], what: str) -> None:
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise ValueError(f"{what} lacks the columns {missing} (it needs {list(columns)})")


def seed_values(metrics: pd.DataFrame, steps: pd.DataFrame, diameter: float, train: Training) -> pd.DataFrame:
    """One seed's values: a row per method, protocol K (``history``) and quantity, from its metrics.csv and
    metrics_per_step.csv (as the evaluate stage writes them), the mean diameter and its model's training."""
    _needs(metrics, ("method", "metric", "sim", "history", "mse", "mean_prediction", "n_sims", "n_blown_up",
                     "split"), "metrics.csv")
    _needs(steps, ("method", "metric", "sim", "history", "tau", "prediction"), "metrics_per_step.csv")
    overall = metrics[metrics["sim"] == "all"]
    per_sim = steps[(steps["metric"] == MSE) & (steps["sim"] != "all")]
    # the mean over sims per frame, from the per-sim rows; a blown-up sim's NaN frames make it NaN
    frames = per_sim.groupby(["method", "history", "tau"])["prediction"].mean(skipna=False)
    rows = []
    mse_rows = overall[overall["metric"] == MSE]
    if mse_rows.empty:
        raise ValueError(f"metrics.csv has no overall '{MSE}' rows (sim = all)")
    for row in mse_rows.itertuples(index=False):
        method, k = str(row.method), int(row.history)
        try:
            curve = frames.loc[(method, k)]
        except KeyError:
            raise ValueError(f"metrics_per_step.csv has no per-sim '{MSE}' rows of {method} under K = {k}, which "
                             f"metrics.csv scores; both must come from the same evaluation") from None
        base = {"method": method, "history": k, "n_predicted": int(curve.index.max()), "n_sims": int(row.n_sims)}
        mse = float(row.mse)
        rows += [{**base, "quantity": "rollout_mse", "value": mse},
                 {**base, "quantity": "mse_first_frame", "value": float(curve.loc[curve.index.min()])},
                 {**base, "quantity": "mse_last_frame", "value": float(curve.loc[curve.index.max()])},
                 {**base, "quantity": "rmse_diameters", "value": math.sqrt(mse) / diameter if mse >= 0 else math.nan},
                 {**base, "quantity": "blown_up", "value": float(row.n_blown_up)}]
        timing = overall[(overall["metric"] == SECONDS) & (overall["method"] == method) & (overall["history"] == k)]
        if len(timing):
            rows.append({**base, "quantity": "rollout_ms_per_frame",
                         "value": 1000.0 * float(timing["mean_prediction"].iloc[0])})
    model = {"method": MODEL, "history": NOT_APPLICABLE, "n_predicted": NOT_APPLICABLE, "n_sims": NOT_APPLICABLE}
    rows += [{**model, "quantity": "train_seconds", "value": train.seconds},
             {**model, "quantity": "train_cost", "value": train.hours}]
    table = pd.DataFrame(rows)
    table["unit"] = [train.unit if q == "train_cost" else QUANTITIES[q][0] for q in table["quantity"]]
    return table


def _split(tables: dict[int, pd.DataFrame]) -> tuple[str, str]:
    """The split every seed was scored on and its note (the same evaluation for every seed)."""
    seen = {(str(t["split"].iloc[0]), str(t["split_note"].iloc[0]) if "split_note" in t and
             pd.notna(t["split_note"].iloc[0]) else "") for t in tables.values()}
    if len(seen) != 1:
        raise ValueError(f"the seeds were scored on different splits: {sorted(seen)}; a card compares one split")
    return next(iter(seen))


def combine(values: dict[int, pd.DataFrame], benchmark: str, split: str) -> pd.DataFrame:
    """The measured rows of the card: each (method, K, quantity) of :func:`seed_values` over the seeds."""
    if not values:
        raise ValueError("no seeds to combine: the card needs at least one seed's evaluation")
    stacked = pd.concat([t.assign(seed=int(s)) for s, t in values.items()], ignore_index=True)
    seeds = sorted(values)
    rows = []
    for (method, k, quantity), group in stacked.groupby(["method", "history", "quantity"], sort=False):
        missing = sorted(set(seeds) - set(group["seed"]))
        if missing:
            raise ValueError(f"{quantity} of {method} under K = {k}: seeds {missing} have no value (each seed must "
                             f"be evaluated under the same protocols)")
        units, sims = sorted(set(group["unit"])), sorted(set(group["n_sims"]))
        if len(units) > 1:
            by_unit = {u: sorted(group.loc[group["unit"] == u, "seed"]) for u in units}
            raise ValueError(f"{quantity} of {method}: the models trained on different hardware ({by_unit}); a card "
                             f"compares models trained alike")
        if len(sims) > 1:
            raise ValueError(f"{quantity} of {method} under K = {k}: the seeds scored different numbers of sims "
                             f"({sims}); each seed must be scored on the same sims")
        series = group.set_index("seed")["value"].astype(float).sort_index()
        rows.append({"benchmark": benchmark, "source": MEASURED, "method": method, "history": k,
                     "n_predicted": group["n_predicted"].iloc[0],
                     "split": NOT_APPLICABLE if k == NOT_APPLICABLE else split, "quantity": quantity,
                     "unit": units[0], **summary(series),
                     "total": float(series.sum(skipna=False)) if quantity == "blown_up" else NOT_APPLICABLE,
                     "n_sims": sims[0]})
    return pd.DataFrame(rows, columns=list(COLUMNS))


def together(trainings: dict[int, Training]) -> Training:
    """The training of an ensemble of these models: their wall seconds and core- (or GPU-) hours summed."""
    if not trainings:
        raise ValueError("an ensemble needs at least one model's training")
    units = sorted({t.unit for t in trainings.values()})
    if len(units) > 1:
        raise ValueError(f"the ensemble's models trained on different hardware ({units}); their costs have no "
                         "common unit")
    return Training(seconds=float(sum(t.seconds for t in trainings.values())),
                    hours=float(sum(t.hours for t in trainings.values())), unit=units[0],
                    hardware=tuple(dict.fromkeys(h for t in trainings.values() for h in t.hardware)),
                    recorded=all(t.recorded for t in trainings.values()))


def ensemble_rows(metrics: pd.DataFrame, steps: pd.DataFrame, diameter: float, trainings: dict[int, Training],
                  benchmark: str, split: str) -> pd.DataFrame:
    """The card's rows of the seed ensemble (module docstring) from its one evaluation (metrics.csv and
    metrics_per_step.csv of ``graphdem evaluate`` with every seed's checkpoint; its Graph-DEM rows are the
    ensemble's) and its models' trainings. Its constant velocity rows are the seeds' own and are left out."""
    if len(trainings) < 2:
        raise ValueError(f"a seed ensemble needs at least two models; got {len(trainings)}")
    values = seed_values(metrics, steps, diameter, together(trainings))      # checks metrics.csv's columns
    scored = str(metrics["split"].iloc[0])
    if scored != split:
        raise ValueError(f"the seed ensemble was scored on the {scored!r} split, the seeds on {split!r}; the card "
                         "compares one split")
    values = values[values["method"] == MODEL]
    rows = [{"benchmark": benchmark, "source": MEASURED, "method": ENSEMBLE, "history": v.history,
             "n_predicted": v.n_predicted, "split": NOT_APPLICABLE if v.history == NOT_APPLICABLE else split,
             "quantity": v.quantity, "unit": v.unit, "mean": float(v.value), "std": NOT_APPLICABLE,
             "min": NOT_APPLICABLE, "max": NOT_APPLICABLE,
             "total": float(v.value) if v.quantity == "blown_up" else NOT_APPLICABLE, "n_seeds": len(trainings),
             "n_sims": v.n_sims, "values": "+".join(map(str, sorted(trainings)))}
            for v in values.itertuples(index=False)]
    return pd.DataFrame(rows, columns=list(COLUMNS))


def article_rows(article: dict, diameter: float, benchmark: str) -> pd.DataFrame:
    """The article's figures (the config's ``B.article``: ``history``, ``split``, ``rollout_mse`` per method) as
    card rows of ``source = article``, with their RMSE in the same mean diameters."""
    missing = {"history", "split", "rollout_mse"} - set(article)
    if missing:
        raise ValueError(f"the article's figures need the keys history, split and rollout_mse; missing "
                         f"{sorted(missing)}")
    rows = []
    for method, mse in article["rollout_mse"].items():
        base = {"benchmark": benchmark, "source": ARTICLE, "method": method, "history": int(article["history"]),
                "n_predicted": NOT_APPLICABLE, "split": article["split"], "std": NOT_APPLICABLE,
                "min": NOT_APPLICABLE, "max": NOT_APPLICABLE, "total": NOT_APPLICABLE, "n_seeds": NOT_APPLICABLE,
                "n_sims": NOT_APPLICABLE, "values": NOT_APPLICABLE}
        rows += [{**base, "quantity": "rollout_mse", "unit": QUANTITIES["rollout_mse"][0], "mean": float(mse)},
                 {**base, "quantity": "rmse_diameters", "unit": QUANTITIES["rmse_diameters"][0],
                  "mean": math.sqrt(float(mse)) / diameter}]
    return pd.DataFrame(rows, columns=list(COLUMNS))


def card(tables: dict[int, tuple[pd.DataFrame, pd.DataFrame, Training]], stats: dict, article: dict,
         benchmark: str, ensemble: tuple[pd.DataFrame, pd.DataFrame] | None = None) -> tuple[pd.DataFrame, str, str]:
    """card.csv's table from each seed's (metrics.csv, metrics_per_step.csv, training), the dataset's stats.json
    and the article's figures; also the split scored and its note. ``ensemble``: the seed ensemble's
    (metrics.csv, metrics_per_step.csv), scored with every seed's model (:func:`ensemble_rows`)."""
    diameter = mean_diameter(stats)
    split, note = _split({s: m for s, (m, _, _) in tables.items()})
    values = {s: seed_values(m, st, diameter, tr) for s, (m, st, tr) in tables.items()}
    parts = [combine(values, benchmark, split)]
    if ensemble is not None:
        parts.append(ensemble_rows(*ensemble, diameter, {s: tr for s, (_, _, tr) in tables.items()}, benchmark,
                                   split))
    table = pd.concat([*parts, article_rows(article, diameter, benchmark)], ignore_index=True)
    return table, split, note


def _number(value, digits: int = 4) -> str:
    return "NaN" if pd.isna(value) else f"{float(value):.{digits}g}"


def _cell(row: pd.Series) -> str:
    """A measured cell: mean +- std [min .. max] over the seeds; blow-ups as the count over all seeds."""
    if row["source"] == ARTICLE:
        return _number(row["mean"], 5)
    if row["method"] == ENSEMBLE:
        if row["quantity"] == "blown_up":
            return f"{_number(row['total'])} of {int(row['n_sims'])}"
        per = " in all" if row["quantity"] in ("train_seconds", "train_cost") else ""
        return f"{_number(row['mean'])} ({int(row['n_seeds'])} models{per})"
    if row["quantity"] == "blown_up":
        return f"{_number(row['total'])} of {int(row['n_sims']) * int(row['n_seeds'])}"
    if int(row["n_seeds"]) == 1:
        return f"{_number(row['mean'])} (1 seed)"
    if pd.isna(row["mean"]):
        undefined = [v.split(":")[0] for v in str(row["values"]).split() if v.endswith(":nan")]
        return f"NaN (seeds {', '.join(undefined)})" if undefined else "NaN"
    return f"{_number(row['mean'])} ± {_number(row['std'], 2)} [{_number(row['min'])} .. {_number(row['max'])}]"


def markdown(table: pd.DataFrame, benchmark: str, split: str, note: str, diameter: float,
             trainings: dict[int, Training], device: str) -> str:
    """card.md: the card as a short table a person reads, with the split scored, the seeds, the hardware and the
    article's figures beside ours. ``device`` is the device setting the evaluate jobs were given."""
    measured = table[table["source"] == MEASURED]
    seeds = sorted(trainings)
    def first_ours(names) -> list[str]:          # Graph-DEM, then constant velocity, then the rest as given
        names = list(dict.fromkeys(names))
        return sorted(names, key=lambda m: (m != MODEL, m != BASELINE, names.index(m)))
    methods = [(MEASURED, m) for m in first_ours(measured["method"])]
    methods += [(ARTICLE, m) for m in first_ours(table.loc[table["source"] == ARTICLE, "method"])]
    article = table[table["source"] == ARTICLE]
    heads = [LABELS.get(m, m) if s == MEASURED else f"article: {LABELS.get(m, m)}" for s, m in methods]
    n_sims = int(measured.loc[measured["quantity"] == "rollout_mse", "n_sims"].iloc[0])
    lines = [f"# Benchmark card: {benchmark}", "",
             f"Scored on the **{split}** split ({n_sims} sims per seed)" + (f": {note}" if note else "") + ".",
             f"Seeds {', '.join(map(str, seeds))}: one model per seed, each scored by the same evaluation. A cell is "
             f"the mean ± standard deviation (ddof 1) [smallest .. largest] over the seeds; NaN where a seed's "
             f"rollout blew up (the seeds named).",
             ]
    if len(article):
        first = article.iloc[0]
        lines.append(f"Article columns: its Table 6 (K = {first['history']}, {first['split']} split), from the "
                     f"config's `{benchmark}.article`" + (f"; ours are on {split}, not {first['split']}"
                                                         if first["split"] != split else "") + ".")
    lines += ["", "| quantity | K | " + " | ".join(heads) + " |", "| --- | --- |" + " --- |" * len(heads)]
    order = list(QUANTITIES)
    keys = table[["quantity", "history"]].drop_duplicates()
    keys = keys.assign(_q=keys["quantity"].map(order.index),
                       _k=pd.to_numeric(keys["history"].replace(NOT_APPLICABLE, np.nan)))
    for key in keys.sort_values(["_q", "_k"]).itertuples(index=False):
        here = table[(table["quantity"] == key.quantity) & (table["history"].astype(str) == str(key.history))]
        unit = here["unit"].iloc[0]
        label = f"{QUANTITIES[key.quantity][1]} ({unit})"
        if key.history == NOT_APPLICABLE:
            k = "all"
        else:
            predicted = here.loc[here["source"] == MEASURED, "n_predicted"]
            k = f"{key.history}" + (f" ({int(predicted.iloc[0])} predicted)" if len(predicted) else "")
        cells = []
        for source, method in methods:
            match = here[(here["source"] == source) & (here["method"] == method)]
            cells.append(_cell(match.iloc[0]) if len(match) else "")
        lines.append(f"| {label} | {k} | " + " | ".join(cells) + " |")
    hardware = sorted({h.describe() for t in trainings.values() for h in t.hardware})
    assumed = [s for s, t in trainings.items() if not t.recorded]
    if (measured["method"] == ENSEMBLE).any():
        lines += ["", "Seed ensemble: the seeds' models as one simulator that integrates the mean of their "
                      "accelerations every step, scored once on the same sims; it costs every model's training and "
                      "one forward pass per model per frame."]
    lines += ["", f"Mean particle diameter d = {diameter:.4g} m: the moving particles of the train split "
                  "(the dataset's stats.json); RMSE in diameters = sqrt(rollout MSE) / d.",
              f"Training hardware: {'; '.join(hardware)}"
              + (f" (seeds {assumed}: not recorded in history.csv, assumed from the workflow's settings)"
                 if assumed else "") + ".",
              f"Rollout times: `graphdem evaluate`'s rollouts, device setting `{device}`.",
              "Definitions: docs/benchmarks.md, \"Benchmark card\"; the numbers: card.csv."]
    return "\n".join(lines) + "\n"
