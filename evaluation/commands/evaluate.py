"""`graphdem evaluate` (rollout MSE and scene metrics of a checkpoint beside constant velocity and the DEM
ensemble, evaluation/evaluate.py) and `graphdem combine` (stack its tables)."""

from __future__ import annotations

import json
from pathlib import Path

from evaluation.commands import metric_options
from generators import cli as gcli
from generators.cli_paths import input_path, output_file, output_folder, split_table
from surrogate.commands import options


def register(sub) -> None:
    p = gcli.add_command(sub, "evaluate", run_evaluate,
                         help="rollout MSE and scene metrics of a checkpoint on H5MD sims")
    options.checkpoint_and_data(p, data_required=False, ensemble=True)
    p.add_argument("--splits", type=split_table, help="a split table (id, split, path); evaluates the sims of --split")
    p.add_argument("--split", choices=("auto", "test", "valid"), default="test",
                   help="which split the sims are (with --data) or which to take from --splits; auto: test where "
                        "the table has one, else valid (said in every output)")
    p.add_argument("--history", type=int, nargs="+",
                   help="K of each protocol: frames given from the data and not scored; at least the history "
                        "length the checkpoint reads (more: each step still reads its last frames). Several K: "
                        "one table with a row set per K (the history column), plots of all, the GIF of the first. "
                        "Default: the history the checkpoint reads")
    p.add_argument("--out", type=output_file, required=True, help="metrics CSV to write")
    p.add_argument("--per-step", type=output_file, help="per-step CSV (truth and prediction per metric and frame)")
    p.add_argument("--table-html", type=output_file,
                   help="metrics CSV as an HTML table whose empty cells say n/a or undefined and why (the report's)")
    p.add_argument("--rollouts", type=input_path, help="folder of rollouts made by this checkpoint (else roll out now)")
    p.add_argument("--ensemble", type=input_path, nargs="+",
                   help="the DEM ensemble's member folders, <sim id>.h5 per sim in each: the sim rerun by its engine "
                        "from its own state at the last given frame, perturbed; scored member by member (method "
                        "dem_ensemble) and as the members' mean (dem_ensemble_mean), and their spread is the unit "
                        "of every method's error_in_spreads")
    p.add_argument("--intervals-json", type=json.loads, default=None,
                   help='the bootstrap of every figure\'s interval, {"samples": N, "level": L, "seed": S} (default: '
                        "the config's intervals)")
    metric_options.scene_metric_options(p)
    p.add_argument("--plots", type=output_folder, help="folder for metrics_over_frames.png and rollout.gif")
    p.add_argument("--animate", help="sim id to animate (default: the first)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")

    p = gcli.add_command(sub, "combine", run_combine,
                         help="stack CSV tables of the same columns (e.g. one per protocol)")
    p.add_argument("--tables", type=input_path, nargs="+", required=True)
    p.add_argument("--union", action="store_true", help="tables may have different columns (blank where missing)")
    p.add_argument("--out", type=output_file, required=True)


def run_evaluate(args) -> None:
    """Evaluate a checkpoint on every H5MD sim in --data (all of them as test): rollout MSE per sim and overall, and
    the scene's metrics (docs/surrogate.md) where the scene is known, beside a constant-velocity baseline and, with
    --ensemble, the DEM ensemble (the DEM's own chaos). Acc is the article's, of the test-set mean curve
    (acc_percent), beside the pooled one (acc_pooled_percent). The sims are --data, or one split of a --splits
    table. Several --checkpoint: their ensemble is scored as Graph-DEM. A model trained on user data (graphdem dataset
    --user-data, docs/user-data.md) is scored by the generic metrics only, whatever scene its sims name: rollout MSE
    and plausibility (overlaps, particles outside the box and through a wall, kinetic energy)."""
    options.log_to_stderr()
    if args.history is None:
        args.history = [checkpoint_history(args.checkpoint)]
    split, data, note = _split(args)
    if note:
        print(f"NOTE: {note}")
    if args.rollouts is not None and len(args.history) > 1:
        raise SystemExit("graphdem evaluate: --rollouts holds rollouts of one K; give one --history with it")
    table, steps, sims, config = _protocols(args, split, data, note)
    _write_outputs(args, table, steps, sims, split, config)


def checkpoint_history(paths: list) -> int:
    """The history K the checkpoints read (their model config's ``history``; several must agree)."""
    from surrogate import checkpoint
    ks = {int(checkpoint.load(p, map_location="meta")["json"]["model"]["history"]) for p in paths}
    if len(ks) != 1:
        raise SystemExit(f"graphdem evaluate: the checkpoints read different histories {sorted(ks)}; give --history")
    return ks.pop()


def _write_outputs(args, table, steps, sims, split: str, config) -> None:
    """--out with its config sidecar (evaluation/config_sidecar.py), --per-step, --table-html and the --plots: all
    of them or none. Each is written under a temporary
    name and they are renamed into place together once every one is written: a failed write (a full disk, a
    file-size limit, a plot that fails) leaves the previous outputs as they were, and the error names the file."""
    from evaluation import evaluate
    from generators.atomic import atomic_outputs
    scene = str(table["scene"].iloc[0])
    name = str(sims[0].traj.parameters.get("dataset", scene))
    with atomic_outputs() as output:
        metrics = evaluate.write(table, steps, args.out, args.per_step, output, config)
        if args.table_html:
            from evaluation import metrics_table
            with output(args.table_html) as tmp:
                metrics_table.write(metrics, tmp, f"{name}: Graph-DEM, constant velocity"
                                    + (" and the DEM ensemble" if args.ensemble else "") + f" on the {split} sims")
        if args.plots:
            _plots(args, steps, sims, name, split, output, nominal_time=scene == "solidgn")


def _split(args) -> tuple[str, list, str]:
    """The split scored, the sims (--data, or the split's rows of --splits) and a note on the choice."""
    import pandas as pd

    from evaluation import evaluate
    if (args.data is None) == (args.splits is None):
        raise SystemExit("graphdem evaluate: give either --data (H5MD files or folders) or --splits (a split table)")
    if args.splits is not None:
        return evaluate.evaluation_split(pd.read_csv(args.splits), args.split)
    if args.split == "auto":
        raise SystemExit("graphdem evaluate: --split auto needs --splits; with --data name the split "
                         "(test or valid)")
    return args.split, args.data, ""


def _protocols(args, split: str, data, note: str):
    """One protocol per K of --history, stacked (the ``history`` column tells them apart): the metrics, the
    per-step table, the first protocol's sims and the config scored (the same checkpoints under every K)."""
    import pandas as pd

    from evaluation import evaluate
    tables, per_step, first, config = [], [], None, None
    for k in args.history:
        table, steps, sims, config = evaluate.evaluate(args.checkpoint, data, k, rollouts_dir=args.rollouts,
                                               body_displacement=args.body_displacement, frames=args.frames,
                                               ensemble_dir=args.ensemble,
                                               threads=args.threads, progress=not args.no_progress, split=split,
                                               split_note=note, runtime=options.runtime_config(args),
                                               allow_other_scene=args.allow_other_scene, device=args.device,
                                               intervals=metric_options.intervals(args))
        tables.append(table)
        per_step.append(steps)
        first = first or sims
        print(f"K = {k}:\n{evaluate.report(table)}")
    return pd.concat(tables, ignore_index=True), pd.concat(per_step, ignore_index=True), first, config


def _plots(args, steps, sims, name: str, split: str, output, nominal_time: bool) -> None:
    """--plots: the metrics over the frames, and the GIF of --animate (or the first sim) beside the DEM, staged in
    ``output`` (generators.atomic.atomic_outputs). ``nominal_time``: the sims store a nominal dt (Solid-GN), frames
    are the honest axis."""
    from evaluation import evaluate, plots
    ks = ", ".join(str(k) for k in args.history)
    with output(Path(args.plots) / "metrics_over_frames.png") as tmp:
        plots.metrics_over_frames(evaluate.mean_per_step(steps), tmp,
                                  f"{name}: mean over {len(sims)} {split} sims, K = {ks}"
                                  + ("\n(scored on valid, not a held-out test split)" if split == "valid" else ""),
                                  x="tau" if nominal_time else "time")
    pick = next((s for s in sims if s.id == args.animate), sims[0]) if sims else None
    if pick is None:
        return
    t = pick.traj
    names = {int(k): v for k, v in dict(t.parameters.get("species_names") or {}).items()}
    truth, pred, radius = pick.truth, pick.predictions[evaluate.MODEL], t.radius
    title = f"{name} {pick.id}: DEM (left) and Graph-DEM (right)"
    if truth.shape[-1] == 3:           # a 3D scene: the section by its split plane (shear box)
        height = float(t.parameters.get("split_height", 0.5 * (t.box_lower[2] + t.box_upper[2])))
        (truth, radius_truth), (pred, radius_pred) = (plots.plane_section(p, radius, height) for p in (truth, pred))
        radius = (radius_truth, radius_pred)
        title += f"\nsection z = {1000 * height:.1f} mm (the box's split plane), seen from above"
    with output(Path(args.plots) / "rollout.gif") as tmp:
        plots.animation(tmp, truth, pred, radius, t.species, t.time, t.box_lower[:2], t.box_upper[:2],
                        args.history[0], title, names)


def run_combine(args) -> None:
    """Stack CSV tables of the same columns (e.g. one metrics.csv per protocol K) in the order given; --union:
    tables of different columns, blank where a table has no such column. Where the rows name one config
    (config_sha) and a table's config sidecar holds it, it is written beside --out too (docs/surrogate.md)."""
    from evaluation import config_sidecar
    from evaluation.evaluate import combine
    table = combine(args.tables, union=args.union)
    options.write_table(table, args.out)
    print(f"{args.out}: {len(table)} rows from {len(args.tables)} tables")
    shas = table["config_sha"].dropna().astype(str).tolist() if "config_sha" in table else []
    carried = config_sidecar.carry(args.tables, shas, args.out)
    if carried:
        print(carried)
