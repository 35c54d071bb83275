"""Fingerprints of a ci-scale run's outputs: what the pinned-output test compares.

``python -m tests.workflow.fingerprint RESULTS OUT.json`` writes the fingerprints of RESULTS (a
workflow's results/ folder) for every scene found there. Pinned per scene:

- the sweep table, column order aside (values exact);
- the settled packings' content keys;
- every sim's H5MD positions, bit for bit (SHA-256 of the float32 array);
- metrics.csv's values: the truth and constant-velocity rows exactly (numpy float64 from the
  positions); Graph-DEM's to a relative 1e-5: training on two torch threads is not bitwise
  repeatable (two runs of the same commit differ by ~1e-8 in the loss, and a fresh-clone run gave a
  meteorite rollout MSE 2.5e-6 apart from the pinned one), and torch's CPU kernels
  round differently on CPUs with other vector units. Provenance columns (checkpoint digest, config
  digest, code version) are left out; the config itself lies in the sidecar beside metrics.csv
  (evaluation/config_sidecar.py), not in the table.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import h5py
import pandas as pd

PROVENANCE = ("checkpoint", "checkpoint_sha", "config_sha", "code_version")


def sweep_table(path: Path) -> dict:
    table = pd.read_csv(path)
    return {c: [None if pd.isna(v) else str(v) for v in table[c]] for c in sorted(table.columns)}


def positions(path: Path) -> str:
    with h5py.File(path, "r") as f:
        return hashlib.sha256(f["particles/all/position/value"][()].tobytes()).hexdigest()


def metrics(path: Path) -> list[dict]:
    table = pd.read_csv(path, dtype={"acc_frames": str})
    table = table.drop(columns=[c for c in PROVENANCE if c in table.columns])
    return json.loads(table.to_json(orient="records", double_precision=15))


def fingerprint(results: Path, scene: str) -> dict:
    res = Path(results) / scene
    return {"sweep": sweep_table(res / "sweep.csv"),
            "packings": sorted(p.name for p in (res / "packings").iterdir() if not p.name.startswith(".")),
            "positions": {p.stem: positions(p) for p in sorted((res / "sims").glob("*.h5"))},
            "metrics": metrics(res / "metrics.csv")}


if __name__ == "__main__":
    results, out = Path(sys.argv[1]), Path(sys.argv[2])
    scenes = sorted(p.name for p in results.iterdir() if (p / "metrics.csv").is_file())
    out.write_text(json.dumps({s: fingerprint(results, s) for s in scenes}, indent=1) + "\n")
    print(f"{out}: {scenes}")
