"""A trained model published as a pretrained checkpoint with its model card (surrogate/pretrained/).

The checkpoint keeps the weights and metadata the train stage wrote (so :func:`surrogate.checkpoint.load` reads it
as any other) and adds ``pretrained``: the scene, the runtime switches its test metrics were measured with, the
config hash and code version its metrics record, the source checkpoint's digest and the data it was trained on.
The card is Markdown: those facts, then the scene's summary table between ``graphdem tables`` markers
(``<!-- table: <scene>-summary -->``), which :mod:`evaluation.doc_tables` fills from the metrics and stamps, so
that ``graphdem tables --check`` flags the card when the code that produced its numbers changes.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd

from generators import h5md
from generators.atomic import atomic_outputs
from surrogate import checkpoint, provenance


def data_facts(splits: Path) -> dict:
    """What the model was trained on: sims per split, and the engine, particles, frames and dimension of the first
    sim (the split table's paths, relative to the working directory as the workflow writes them)."""
    table = pd.read_csv(splits)
    counts = {str(k): int(v) for k, v in table["split"].value_counts().sort_index().items()}
    first = h5md.read(table["path"].iloc[0])
    return {"sims": counts, "engine": str(first.parameters.get("engine", "unknown")),
            "particles": first.n_particles, "moving_particles": int((~first.kinematic).sum()),
            "frames": first.n_frames, "dim": first.dim,
            "frame_interval_s": float(first.time[1] - first.time[0]) if first.n_frames > 1 else None}


def recorded(metrics: pd.DataFrame, column: str) -> str:
    """The one value of ``column`` the metrics record ('' where none); several are refused (mixed runs)."""
    values = metrics[column].dropna().astype(str).unique() if column in metrics else []
    if len(values) > 1:
        raise ValueError(f"the metrics mix several {column} values ({', '.join(values)}): score one run")
    return str(values[0]) if len(values) else ""


def example_mse(metrics: pd.DataFrame, sim: str) -> float:
    """Graph-DEM's rollout MSE (m²) on the test sim ``sim``, as the metrics record it (its model's first K)."""
    rows = metrics[(metrics["method"] == "graphdem") & (metrics["metric"] == "rollout MSE") & (metrics["sim"] == sim)]
    if len(rows) != 1:
        raise ValueError(f"the metrics hold {len(rows)} Graph-DEM rollout MSE rows of the test sim {sim!r}, not one")
    return float(rows["mse"].iloc[0])


def metadata(scene: str, source: Path, metrics: pd.DataFrame, runtime: dict, data: dict) -> dict:
    """The checkpoint metadata's ``pretrained`` entry."""
    return {"scene": scene, "runtime": runtime, "config_sha": recorded(metrics, "config_sha"),
            "code_version": recorded(metrics, "code_version"), "source_checkpoint": provenance.digest(source),
            "data": data}


def card_text(meta: dict, info: dict, size_bytes: int, parameters: int) -> str:
    """The model card's Markdown, its summary table's markers empty (filled by graphdem tables)."""
    scene, data = info["scene"], info["data"]
    sims = ", ".join(f"{n} {split}" for split, n in data["sims"].items())
    model = meta["model"]
    runtime = ", ".join(f"{k} {v}" for k, v in info["runtime"].items() if k != "compile")
    return "\n".join([
        f"# Pretrained Graph-DEM: {scene}",
        "",
        f"Load it with `graphdem.load_simulator(\"{scene}\")`; made by `graphdem publish` from the workflow's "
        f"results of `snakemake -c2 results/{scene}/metrics.csv` (default scale). docs/pretrained.md says how. "
        f"`{scene}_example.h5` beside it is its first test sim (`surrogate.pretrained.example(\"{scene}\")`).",
        "",
        "| | |",
        "| --- | --- |",
        f"| data | {sims} sims of the {scene} scene, {data['engine']}, {data['particles']} particles "
        f"({data['moving_particles']} moving), {data['frames']} frames {data['frame_interval_s']:.4g} s apart, "
        f"{data['dim']}D |",
        f"| model | K = {model['history']}, latent {model['latent']}, {model['message_passing']} message-passing "
        f"steps, {parameters} weights ({size_bytes / 1e6:.2f} MB) |",
        f"| training | best epoch {meta.get('epoch')}, valid rollout MSE "
        f"{meta.get('valid_rollout_mse', float('nan')):.4g} m² |",
        f"| runtime of the test metrics | {runtime} |",
        f"| config hash | {info['config_sha'] or 'not recorded'} |",
        f"| code version | {info['code_version'] or 'not recorded'} |",
        f"| source checkpoint | sha256 {info['source_checkpoint']} |",
        "",
        "## Test metrics",
        "",
        "Graph-DEM beside constant velocity (same runtime switches) and the DEM ensemble (reruns from the last given "
        "frame, perturbed), with 95 % bootstrap intervals over the test sims (docs/surrogate.md, The yardstick):",
        "",
        f"<!-- table: {scene}-summary -->",
        f"<!-- /table: {scene}-summary -->",
        ""])


def publish(scene: str, source: Path, splits: Path, metrics_csv: Path, runtime: dict, out_dir: Path,
            results: Path) -> tuple[Path, Path]:
    """Write ``<out_dir>/<scene>.pt``, ``<scene>.md`` (its card, the summary table generated from ``results``
    by :mod:`evaluation.doc_tables`) and ``<scene>_example.h5`` (a copy of the first test sim); return the
    checkpoint's and the card's paths."""
    from evaluation import doc_tables
    from evaluation.tables import read_csv
    stored = checkpoint.load(source)
    metrics = read_csv(metrics_csv)
    table = pd.read_csv(splits)
    example = str(table.loc[table["split"] == "test", "id"].iloc[0])
    info = {**metadata(scene, Path(source), metrics, runtime, data_facts(splits)),
            "example": {"sim": example, "rollout_mse": example_mse(metrics, example)}}
    meta = {**stored["json"], "pretrained": info}
    out_dir.mkdir(parents=True, exist_ok=True)
    pt, md = out_dir / f"{scene}.pt", out_dir / f"{scene}.md"
    parameters = sum(int(t.numel()) for t in stored["model"].values())
    with atomic_outputs() as output:            # the three appear together, or none (the old ones stay)
        with output(pt) as tmp_pt:
            checkpoint.save(tmp_pt, {"model": stored["model"], "json": meta})
        with output(out_dir / f"{scene}_example.h5") as tmp:
            shutil.copyfile(table.loc[table["id"] == example, "path"].iloc[0], tmp)
        with output(md) as tmp_md:
            tmp_md.write_text(card_text(meta, info, tmp_pt.stat().st_size, parameters))
            doc_tables.write(doc_tables.plan(Path(results).parent, [tmp_md], Path(results)))
    return pt, md
