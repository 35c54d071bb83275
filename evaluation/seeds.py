"""The spread over training seeds (docs/surrogate.md, "Seeds"): the same scene or benchmark trained with
``seeds`` seeds, each model scored by the same evaluation, and every metric's mean and spread.

One row per method, metric, protocol K (``history``) and value column that has a value (``acc_percent``,
``acc_pooled_percent``, ``mse``, ``mean_prediction``; the rollout MSE's figure is its ``mse`` alone): the mean,
the sample standard deviation (ddof 1), the
smallest and largest value, the number of seeds, and each seed's value (``values``, ``seed:value``). A seed
whose model blew up on a sim has NaN there, which makes the mean NaN: a spread is never taken over the seeds
that happened to work.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from evaluation.tables import read_csv

VALUES = ("acc_percent", "acc_pooled_percent", "mse", "mean_prediction")
KEYS = ("scene", "method", "metric", "history")


def spread(tables: dict[int, pd.DataFrame]) -> pd.DataFrame:
    """Mean and spread of every metric over the seeds' metrics tables (seed -> metrics.csv as read)."""
    if len(tables) < 1:
        raise ValueError("no seeds' metrics to combine")
    rows, parts = [], []
    for seed, table in tables.items():
        overall = table[table["sim"] == "all"].copy()
        if "history" not in overall.columns:
            overall["history"] = np.nan
        overall["seed"] = int(seed)
        parts.append(overall)
    stacked = pd.concat(parts, ignore_index=True)
    for key, group in stacked.groupby(list(KEYS), sort=False, dropna=False):
        for column in VALUES:
            if column not in group.columns or group[column].isna().all():
                continue
            values = group.set_index("seed")[column].astype(float)
            rows.append({**dict(zip(KEYS, key, strict=True)), "column": column, **summary(values)})
    return pd.DataFrame(rows)


def summary(values: pd.Series) -> dict:
    """One quantity over the seeds (``values`` indexed by seed): the mean, the sample standard deviation (ddof 1;
    NaN for one seed), the smallest and largest value, the number of seeds and each seed's value
    (``seed:value``). A NaN seed makes every statistic NaN: a spread is never taken over the seeds that worked."""
    return {"mean": float(values.mean(skipna=False)),
            "std": float(values.std(ddof=1, skipna=False)) if len(values) > 1 else float("nan"),
            "min": float(values.min(skipna=False)), "max": float(values.max(skipna=False)),
            "n_seeds": int(len(values)),
            "values": " ".join(f"{s}:{v:.6g}" for s, v in values.items())}


def read(paths: list[Path], seeds: list[int]) -> dict[int, pd.DataFrame]:
    """The metrics tables of ``seeds`` (in the same order as ``paths``)."""
    if len(paths) != len(seeds):
        raise ValueError(f"{len(paths)} metrics tables for {len(seeds)} seeds; give one table per seed")
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds {seeds} repeat a seed")
    return {int(s): read_csv(p) for s, p in zip(seeds, paths, strict=True)}
