"""`graphdem`: the command line of the pipeline; each Snakemake rule calls one subcommand.

The generators' stages (config, sweep, prepare, simulate, convert, inspect, import-solidgn,
stability-dem) come from generators/cli.py; this module adds the surrogate's (dataset, train, rollout,
evaluate, combine, seeds, card, stability-surrogate, property-test, stress-readout, stress-test, the
performance stage's subcommands, and tables: the docs' results tables, surrogate/doc_tables/) and runs them all.
Every subcommand writes its outputs atomically and exits non-zero with a one-line reason (naming the
file, sim, frame or config key) when something is wrong.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from generators import cli as gcli
from generators import scenes

_json = gcli.json_arg


def cmd_dataset(args) -> None:
    import pandas as pd

    from generators import h5md, plots
    from surrogate import dataset
    table = pd.read_csv(args.table)
    if "path" not in table.columns:
        if args.sims is None:
            raise SystemExit(f"graphdem dataset: {args.table} has no path column; give --sims, the folder of <id>.h5")
        table = dataset.split_table(table, Path(args.sims))
    stats = dataset.build(table, Path(args.out_dir), args.connectivity_radius, args.max_neighbours)
    print(json.dumps(stats, indent=2))
    counted = stats["neighbour_counts"]
    line = (f"neighbours within R = {stats['connectivity_radius']:g} on the train split: at most {counted['max']}, "
            f"99th percentile {counted['p99']}, mean {counted['mean']:.3g} per receiver")
    if counted["max_neighbours"] is not None:
        line += (f"; a cap of {counted['max_neighbours']} truncates {100 * counted['capped_receiver_fraction']:.3g} % "
                 f"of the receivers and drops {100 * counted['dropped_edge_fraction']:.3g} % of the edges")
    print(line)
    floors = {k: v for k, v in (stats.get("contact_miss_floor") or {}).items() if v is not None}
    if floors:
        print("contacts of the next frame missed at R: at most "
              + ", ".join(f"{100 * float(k):g} % for R > {v:.4g}" for k, v in floors.items())
              + f" (R = {stats['connectivity_radius']:g} misses {100 * stats['contact_miss_rate']:.3g} %)")
    rate = stats.get("contact_miss_rate")
    if rate is not None and rate > dataset.CONTACT_MISS_WARNING:
        print(f"WARNING: R = {stats['connectivity_radius']:g} misses {100 * rate:.2g} % of the next frame's contacts "
              f"on the train split (their pair is R or farther apart one frame earlier): the model cannot see them "
              f"coming; a larger connectivity_radius closes the gap (docs/surrogate.md)")
    if args.plot:
        splits = pd.read_csv(Path(args.out_dir) / "splits.csv")
        first = splits[splits["split"] == "train"].iloc[0]
        traj = h5md.read(first["path"])
        names = {int(k): v for k, v in dict(traj.parameters.get("species_names") or {}).items()}
        position, radius, lower, upper = traj.position, traj.radius, traj.box_lower, traj.box_upper
        title, ylabel = f"{args.scene}: {first['id']}", "y (m)"
        if traj.dim == 3:                       # a vertical section through the middle, seen from the side
            mid = 0.5 * float(lower[1] + upper[1])
            position, radius = plots.plane_section(position, radius, mid, axis=1)
            lower, upper, ylabel = lower[[0, 2]], upper[[0, 2]], "z (m)"
            title += f", section y = {mid:.4g} m"
        plots.first_last(args.plot, position, radius, traj.species, traj.time, lower, upper, title, names,
                         ylabel=ylabel)

def _logging(quiet: bool = False) -> None:
    """INFO lines on stderr; only warnings where ``quiet`` (the processes of a multi-process training but rank 0)."""
    import logging
    logging.basicConfig(level=logging.WARNING if quiet else logging.INFO,
                        format="%(asctime)s %(name)s %(levelname)s: %(message)s")

def _train_sections(args) -> tuple[dict, dict, str, Path, Path, Path]:
    """The model and train config, the device, and the stats, splits and output folder, of ``graphdem train``:
    from the resolved config's section of --scene (the workflow's keys), or from the rule's resolved sections.
    --device wins over the config's ``device``; without either, auto."""
    if args.model_json is not None or args.train_json is not None:
        if args.model_json is None or args.train_json is None or args.scene or args.config_file or args.set:
            raise SystemExit("graphdem train: --model-json and --train-json (the workflow's resolved sections) go "
                             "together and replace --scene, --config and --set")
        model, train_cfg, where, device = args.model_json, args.train_json, None, args.device or "auto"
    else:
        if not args.scene:
            raise SystemExit("graphdem train: give --scene (a scene or public benchmark: "
                             f"{', '.join(scenes.names() + sorted(gcli.gconfig.BENCHMARKS))}) to train with its "
                             "model and train config")
        resolved = gcli.resolved_config(args)
        section = resolved[args.scene]
        model, train_cfg, where = section["model"], section["train"], Path("results") / args.scene
        device = args.device or resolved["device"]
    paths = []
    for value, default in ((args.stats, "dataset/stats.json"), (args.splits, "dataset/splits.csv"),
                           (args.out_dir, "model")):
        if value is None and where is None:
            raise SystemExit("graphdem train: --stats, --splits and --out-dir are needed with --model-json")
        paths.append(Path(value) if value is not None else where / default)
    return model, train_cfg, device, *paths


def cmd_contacts(args) -> None:
    import pandas as pd

    from generators import h5md
    from surrogate.contacts import cap_table
    table = pd.read_csv(args.splits)
    if "path" not in table.columns or "split" not in table.columns:
        raise SystemExit(f"{args.splits}: a dataset's splits.csv (columns id, split, path) is needed")
    paths = [Path(p) for p in table.loc[table["split"] == args.split, "path"]]       # as the other stages read them
    if not paths:
        raise SystemExit(f"{args.splits}: no sim in split {args.split!r} (splits: {sorted(set(table['split']))})")
    paths = paths[: args.sims] if args.sims else paths

    def sims():
        for path in paths:
            traj = h5md.read(path)
            yield traj.position, traj.radius, traj.kinematic

    caps = [None] + sorted(set(args.cap or []))
    rows = cap_table(sims(), sorted(set(args.radius)), caps)
    print(f"{len(paths)} {args.split} sims of {args.splits}: directed next-frame contacts missed by a graph of "
          f"radius R capped at N senders per receiver (surrogate/contacts.py)")
    print("| R | cap | contacts | missed | miss rate | senders per receiver |")
    print("| --- | --- | --- | --- | --- | --- |")
    for row in rows:
        print(f"| {row['connectivity_radius']:g} | {row['cap'] if row['cap'] is not None else 'none'} "
              f"| {row['contacts']} | {row['missed']} | {row['miss_rate']:.3%} | {row['senders_per_receiver']:.2f} |")
    if args.out:
        pd.DataFrame(rows).to_csv(args.out, index=False)


def cmd_train(args) -> None:
    from surrogate import distributed, train
    model, train_cfg, device, stats, splits, out_dir = _train_sections(args)
    main = distributed.World.from_env().main
    _logging(quiet=not main)
    state = train.train(stats, splits, model, train_cfg, out_dir,
                        threads=args.threads, fresh=args.fresh, max_steps=args.max_steps,
                        progress=not args.no_progress, device=device)
    if main:
        print(json.dumps({k: state[k] for k in ("epoch", "step", "best_epoch", "best_mse", "finished", "seconds")}))

def cmd_rollout(args) -> None:
    import torch

    from surrogate import ensemble, evaluate, provenance, rollout
    from surrogate.samples import load_sim
    _logging()
    torch.set_num_threads(max(1, args.threads))
    simulator, metas = ensemble.load(args.checkpoint, args.device)
    meta = metas[0]
    simulator, rt = _runtime(args, simulator)
    sha = provenance.digest(args.checkpoint)
    for path in evaluate.data_files(args.data):
        sim = load_sim(path, meta["stats"], meta["model"].get("properties") or [],
                       allow_other_scene=args.allow_other_scene)
        result = rollout.rollout(simulator, sim, runtime=rt)
        out = rollout.write(Path(args.out_dir) / f"{sim.id}.h5", sim, result, args.checkpoint, sha)
        per_frame = result.seconds / max(result.n_predicted, 1)
        status = "" if result.first_nonfinite is None else f", NON-FINITE from frame {result.first_nonfinite}"
        models = f", {result.models} models averaged" if result.models > 1 else ""
        cap = ("" if result.max_neighbours is None else
               f"; neighbour cap {result.max_neighbours}: {result.timing['capped']} receivers capped and "
               f"{result.timing['dropped']} edges dropped over the predicted frames")
        contacts = ("" if rt is None or rt.contact_correction is None else
                    f"; contact correction: {result.timing['stopped']} particle-steps stopped at a kinematic "
                    f"particle, {result.timing['corrected']} pair-steps pushed apart")
        print(f"{out}: {result.n_predicted} frames predicted in {result.seconds:.2f} s "
              f"({1000 * per_frame:.1f} ms per frame{models}, of which graph building "
              f"{1000 * result.seconds_graph / max(result.n_predicted, 1):.1f} ms{status}){cap}{contacts}")

def cmd_evaluate(args) -> None:
    import pandas as pd

    from surrogate import evaluate, plots
    _logging()
    if (args.data is None) == (args.splits is None):
        raise SystemExit("graphdem evaluate: give either --data (H5MD files or folders) or --splits (a split table)")
    if args.splits is not None:
        split, data, note = evaluate.evaluation_split(pd.read_csv(args.splits), args.split)
    else:
        if args.split == "auto":
            raise SystemExit("graphdem evaluate: --split auto needs --splits; with --data name the split "
                             "(test or valid)")
        split, data, note = args.split, args.data, ""
    if note:
        print(f"NOTE: {note}")
    if args.rollouts is not None and len(args.history) > 1:
        raise SystemExit("graphdem evaluate: --rollouts holds rollouts of one K; give one --history with it")
    tables, per_step, first = [], [], None
    for k in args.history:                   # one protocol per K, stacked (the `history` column tells them apart)
        table, steps, sims = evaluate.evaluate(args.checkpoint, data, k, rollouts_dir=args.rollouts,
                                               body_displacement=args.body_displacement, frames=args.frames,
                                               ensemble_dir=args.ensemble,
                                               threads=args.threads, progress=not args.no_progress, split=split,
                                               split_note=note, runtime=_runtime_config(args),
                                               allow_other_scene=args.allow_other_scene, device=args.device,
                                               intervals=_intervals(args))
        tables.append(table)
        per_step.append(steps)
        first = first or sims
        print(f"K = {k}:\n{evaluate.report(table)}")
    table, steps, sims = pd.concat(tables, ignore_index=True), pd.concat(per_step, ignore_index=True), first
    evaluate.write(table, steps, args.out, args.per_step)
    scene = str(table["scene"].iloc[0])
    name = str(sims[0].traj.parameters.get("dataset", scene))
    if args.table_html:
        from surrogate import metrics_table
        metrics_table.write(args.out, args.table_html, f"{name}: Graph-DEM, constant velocity"
                            + (" and the DEM ensemble" if args.ensemble else "") + f" on the {split} sims")
    if args.plots:
        nominal_time = scene == "solidgn"         # Solid-GN stores a nominal dt: frames are the honest axis
        ks = ", ".join(str(k) for k in args.history)
        plots.metrics_over_frames(evaluate.mean_per_step(steps), Path(args.plots) / "metrics_over_frames.png",
                                  f"{name}: mean over {len(sims)} {split} sims, K = {ks}"
                                  + ("\n(scored on valid, not a held-out test split)" if split == "valid" else ""),
                                  x="tau" if nominal_time else "time")
        pick = next((s for s in sims if s.id == args.animate), sims[0]) if sims else None
        if pick is not None:
            t = pick.traj
            names = {int(k): v for k, v in dict(t.parameters.get("species_names") or {}).items()}
            truth, pred, radius = pick.truth, pick.predictions[evaluate.MODEL], t.radius
            title = f"{name} {pick.id}: DEM (left) and Graph-DEM (right)"
            if truth.shape[-1] == 3:           # a 3D scene: the section by its split plane (shear box)
                height = float(t.parameters.get("split_height", 0.5 * (t.box_lower[2] + t.box_upper[2])))
                (truth, radius_truth), (pred, radius_pred) = (plots.plane_section(p, radius, height)
                                                              for p in (truth, pred))
                radius = (radius_truth, radius_pred)
                title += f"\nsection z = {1000 * height:.1f} mm (the box's split plane), seen from above"
            plots.animation(Path(args.plots) / "rollout.gif", truth, pred, radius, t.species, t.time,
                            t.box_lower[:2], t.box_upper[:2], args.history[0], title, names)

def cmd_combine(args) -> None:
    from generators.atomic import atomic_path
    from surrogate.evaluate import combine
    table = combine(args.tables, union=args.union)
    with atomic_path(args.out) as tmp:
        table.to_csv(tmp, index=False)
    print(f"{args.out}: {len(table)} rows from {len(args.tables)} tables")

def cmd_seeds(args) -> None:
    from generators.atomic import atomic_path
    from surrogate import seeds
    table = seeds.spread(seeds.read(args.metrics, args.seeds))
    with atomic_path(args.out) as tmp:
        table.to_csv(tmp, index=False)
    shown = table[table["column"].isin(["acc_percent", "mse"])]
    for row in shown.itertuples():
        print(f"{row.method:>18}  {row.metric:<14} {row.column:<11} {row.mean:.4g} +- {row.std:.2g} "
              f"({row.min:.4g} .. {row.max:.4g}, {row.n_seeds} seeds)")

def cmd_card(args) -> None:
    import pandas as pd

    from generators.atomic import atomic_path
    from surrogate import card, devices
    from surrogate import tables as tables_csv
    counts = {"--metrics": len(args.metrics), "--steps": len(args.steps), "--histories": len(args.histories)}
    if set(counts.values()) != {len(args.seeds)}:
        raise SystemExit(f"graphdem card: give one file per seed ({len(args.seeds)} seeds: {args.seeds}); got "
                         + ", ".join(f"{n} {flag}" for flag, n in counts.items()))
    if len(set(args.seeds)) != len(args.seeds):
        raise SystemExit(f"graphdem card: --seeds {args.seeds} repeat a seed")
    def fallback() -> card.Hardware | None:
        """Where a model whose history.csv does not say trained: --train-threads on --device, here resolved."""
        if args.train_threads is None:
            return None
        where = devices.resolve(args.device)
        return card.Hardware(str(where), devices.name(where), int(args.train_threads), 1)

    tables, trainings = {}, {}
    for seed, metrics, steps, history in zip(args.seeds, args.metrics, args.steps, args.histories, strict=True):
        epochs = pd.read_csv(history)
        try:
            trainings[seed] = card.training(epochs, None if card.records_hardware(epochs) else fallback())
        except ValueError as exc:
            raise ValueError(f"{history}: {exc}") from None
        tables[seed] = (tables_csv.read_csv(metrics), tables_csv.read_csv(steps), trainings[seed])
    if (args.ensemble_metrics is None) != (args.ensemble_steps is None):
        raise SystemExit("graphdem card: give both --ensemble-metrics and --ensemble-steps (the seed ensemble's "
                         "evaluation), or neither")
    ensemble = None if args.ensemble_metrics is None else (tables_csv.read_csv(args.ensemble_metrics),
                                                           tables_csv.read_csv(args.ensemble_steps))
    stats = json.loads(Path(args.stats).read_text())
    table, split, note = card.card(tables, stats, args.article_json, args.benchmark, ensemble)
    text = card.markdown(table, args.benchmark, split, note, card.mean_diameter(stats), trainings, args.device)
    with atomic_path(args.out) as tmp:
        table.to_csv(tmp, index=False, na_rep="NaN")
    with atomic_path(args.markdown) as tmp:
        tmp.write_text(text)
    print(text)


def cmd_stability_surrogate(args) -> None:
    import torch

    from generators.atomic import atomic_path
    from surrogate import checkpoint, evaluate, stability
    from surrogate.samples import load_sim
    _logging()
    torch.set_num_threads(max(1, args.threads))
    simulator, meta = checkpoint.simulator_from(args.checkpoint, args.device)
    sims = [load_sim(p, meta["stats"], meta["model"].get("properties") or [], allow_other_scene=args.allow_other_scene)
            for p in evaluate.data_files(args.data)]
    rt = _runtime_config(args, required_by="stability-surrogate")
    table, frames = stability.surrogate_report(simulator, rt, sims, args.lengths, args.noise, args.seed,
                                               args.max_overlap, args.energy_envelope)
    if args.frames_out:
        with atomic_path(args.frames_out) as tmp:
            frames.to_csv(tmp, index=False)
    if args.plot:
        from surrogate import plots
        plots.stability(frames, args.plot, args.title or "long rollouts")
    with atomic_path(args.out) as tmp:
        table.to_csv(tmp, index=False)
    print(table.drop(columns=["cause", "envelope_cause"], errors="ignore").to_string(index=False))

def cmd_property_test(args) -> None:
    from generators.atomic import atomic_path
    from surrogate import plots, property_test, provenance
    if (args.ensemble is None) != (args.sims_dir is None):
        raise SystemExit("graphdem property-test: give --sims-dir and --ensemble together (the sims and their DEM "
                         "ensemble reruns), or neither")
    chaos = (args.sims_dir, args.ensemble) if args.ensemble is not None else None
    table, pairs = property_test.run(tuple(args.runs), args.sims, args.property, provenance.digest(args.checkpoint),
                                     args.history, args.tolerance, chaos)
    if args.plot:
        plots.property_test(pairs, table, args.plot, args.title or f"property test: {args.property}")
    with atomic_path(args.out) as tmp:
        table.to_csv(tmp, index=False)
    print(table.to_string(index=False))


def cmd_stress_readout(args) -> None:
    import pandas as pd

    from generators import h5md
    from generators.atomic import atomic_path
    from surrogate import stress
    _logging()
    splits = pd.read_csv(args.splits)
    samples = {split: [stress.Sample.from_trajectory(h5md.read(p)) for p in splits.loc[splits["split"] == split,
                                                                                     "path"]]
               for split in ("train", "valid")}
    model, meta, history = stress.fit(samples["train"], samples["valid"], args.settings_json,
                                      progress=not args.no_progress, threads=args.threads)
    with atomic_path(args.history) as tmp:
        history.to_csv(tmp, index=False)
    stress.save(args.out, model, meta)
    print(f"stress readout: valid MSE of tau / sigma_n {meta['valid_mse']:.4g} (epoch {meta['epoch']}), "
          f"{len(meta['train_sims'])} train and {len(meta['valid_sims'])} valid sims")


def cmd_stress_test(args) -> None:
    from generators.atomic import atomic_path
    from surrogate import plots, provenance, stress_test
    table, curves = stress_test.run(args.readout, args.sims, args.rollouts, provenance.digest(args.checkpoint),
                                    args.history, args.tolerance, args.ensemble)
    if args.plot:
        plots.stress_curves(curves, table, args.history, args.plot, args.title or "shear stress")
    with atomic_path(args.out) as tmp:
        table.to_csv(tmp, index=False)
    print(table.to_string(index=False))


def _write_rows(rows: list[dict], out: Path) -> None:
    import pandas as pd

    from generators.atomic import atomic_path
    with atomic_path(out) as tmp:
        pd.DataFrame(rows).to_csv(tmp, index=False)

def cmd_performance_dem(args) -> None:
    from surrogate import performance
    rows = args.sims
    packings = [Path(args.packings) / row["packing"] for row in rows]
    result = performance.dem_contender(args.name, args.variant, args.scene, rows, packings, args.truth, args.history,
                                     args.repeats, args.body_displacement, frames=args.frames)
    _write_rows([result], args.out)
    print(json.dumps(result, indent=1, default=str))

def cmd_performance_surrogate(args) -> None:
    from surrogate import performance
    result = performance.surrogate_contender(args.name, args.variant, args.checkpoint,
                                           _runtime_config(args, required_by="performance-surrogate"), args.data,
                                           args.repeats, args.threads, body_displacement=args.body_displacement,
                                           frames=args.frames, device=args.device)
    _write_rows([result], args.out)
    print(json.dumps(result, indent=1, default=str))

def cmd_performance_report(args) -> None:
    import numpy as np
    import pandas as pd

    from generators.atomic import atomic_path
    from surrogate import performance, plots
    from surrogate import tables as tables_csv
    contenders = pd.concat([tables_csv.read_csv(p) for p in args.tables], ignore_index=True)
    from generators import record
    settling = [record.read(p).run.wall_time for p in args.packings or []]
    table = performance.report(contenders, args.main, args.reference, float(np.mean(settling)) if settling else None)
    with atomic_path(args.out) as tmp:
        table.to_csv(tmp, index=False)
    plots.pareto(table, args.plot, args.title)
    if args.substeps_plot:
        plots.speedup_substeps(table, args.main, args.substeps_plot, f"{args.title}: speed-up against DEM sub-steps")
    main = table[table["main"].astype(bool)].iloc[0]
    matched = (f"{main['speedup_vs_matched_dem']:.2f}x faster than {main['matched_dem']} (the fastest DEM at least as "
               f"accurate on the MSE and every scene metric)" if main["matched_dem"] else
               "no DEM contender is as accurate on the MSE and every scene metric")
    print(f"{args.out}: {len(table)} rows; {main['contender']}: {main['seconds_per_frame'] * 1000:.2f} ms per frame, "
          f"{main['speedup_vs_reference']:.1f}x faster than the DEM reference, {matched}, break-even at "
          f"{main['break_even_substeps']:.0f} DEM sub-steps per frame")

def _checkpoint_and_data(p: argparse.ArgumentParser, data_required: bool = True, ensemble: bool = False) -> None:
    if ensemble:
        p.add_argument("--checkpoint", type=Path, nargs="+", required=True,
                       help="a best.pt or last.pt written by train; several: an ensemble, every step the mean of "
                            "their accelerations is integrated (the models must share history, R, the neighbour "
                            "cap, the frame interval, box and types; docs/surrogate.md)")
    else:
        p.add_argument("--checkpoint", type=Path, required=True, help="a best.pt or last.pt written by train")
    p.add_argument("--data", type=Path, nargs="+", required=data_required, help="H5MD files or folders of them")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    p.add_argument("--allow-other-scene", action="store_true",
                   help="score sims of another scene (or other kinematic species) than the checkpoint was trained on")
    p.add_argument("--runtime-json", type=_json,
                   help="the scene's runtime switches (JSON: split_edge_mlp, skip_kinematic_pairs, prune_isolated, "
                        "precision, sleep_speed, keep_in_domain, compile, optionally contact_correction; "
                        "docs/performance.md); default: compute as in training")
    _device(p, "auto")


def _device(p: argparse.ArgumentParser, default: str | None) -> None:
    from surrogate import devices
    p.add_argument("--device", type=_device_arg, default=default,
                   help=f"where the model computes: {devices.CHOICES} (auto: the first CUDA GPU torch sees, else the "
                        "CPU; under torchrun each process takes its LOCAL_RANK's GPU; docs/scaling.md)"
                        + ("" if default else "; default: the config's device key with --scene, else auto"))


def _device_arg(value: str) -> str:
    from surrogate import devices
    if not devices.SPEC.match(value):
        raise argparse.ArgumentTypeError(f"{value!r}: allowed are {devices.CHOICES}")
    return value

def _intervals(args):
    """The bootstrap of --intervals-json (the config's ``intervals`` keys), or None: the config's defaults."""
    from surrogate.metrics.scores import Intervals
    if args.intervals_json is None:
        return None
    want = {"samples", "level", "seed"}
    if not isinstance(args.intervals_json, dict) or set(args.intervals_json) != want:
        raise SystemExit(f"graphdem evaluate: --intervals-json {args.intervals_json!r}: an object with exactly the "
                         f"keys {', '.join(sorted(want))}")
    return Intervals(**args.intervals_json)


def _runtime_config(args, required_by: str | None = None):
    """The Runtime of --runtime-json; None without it, unless the command ``required_by`` needs it."""
    from surrogate import runtime
    if args.runtime_json is None:
        if required_by:
            raise SystemExit(f"graphdem {required_by}: --runtime-json is required (the scene's runtime config)")
        return None
    return runtime.Runtime.from_config(args.runtime_json)

def _runtime(args, simulator):
    """The simulator prepared for the --runtime-json switches, and the Runtime (None without)."""
    from surrogate import runtime
    rt = _runtime_config(args)
    return (simulator, None) if rt is None else (runtime.apply(simulator, rt), rt)

def _body_displacement(p: argparse.ArgumentParser) -> None:
    """The options of the scene metrics: the landslide body threshold and the article's frame set of Acc."""
    p.add_argument("--body-displacement", type=float, help="landslide body threshold (m); default one mean diameter")
    p.add_argument("--frames", type=int, nargs="+", metavar="TAU",
                   help="the predicted frames (tau = 1 is the first) the article-style Acc averages over, e.g. "
                        "5 10 15 20 30 for the meteorite (article Table 2); default: every predicted frame")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="graphdem",
        description="Graph-DEM pipeline: DEM sweeps (LAMMPS, YADE) to H5MD datasets, then training, rollout and "
                    "evaluation of the Graph-DEM surrogate. The Snakemake workflow calls these subcommands; they "
                    f"can also be run by hand. Scenes: {', '.join(scenes.names())}.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    gcli.add_commands(sub)
    names = scenes.names()
    p = sub.add_parser("dataset", help="write splits.csv and stats.json (train split only)",
                       description="Split table and normalisation statistics of the train split. --table is a "
                                   "scene's sweep.csv (id, split; the files are --sims/<id>.h5) or a split table "
                                   "with a path column, such as the one import-solidgn writes.")
    p.add_argument("--scene", choices=names + list(gcli.gconfig.BENCHMARKS), required=True)
    p.add_argument("--table", type=Path, required=True, help="sweep.csv or a split table (id, split[, path])")
    p.add_argument("--sims", type=Path, help="folder of <id>.h5 files, for a table without a path column")
    p.add_argument("--out-dir", type=Path, required=True)
    p.add_argument("--connectivity-radius", type=float, required=True, help="graph radius R (m)")
    p.add_argument("--max-neighbours", type=int,
                   help="a neighbour cap (the model's max_neighbours): stats.json reports the share of receivers "
                        "it truncates and of edges it drops on the train split; default: no cap")
    p.add_argument("--plot", type=Path, help="PNG of the first train sim's first and last frame")
    p.set_defaults(func=cmd_dataset)

    p = sub.add_parser("contacts", help="next-frame contacts a graph of radius R, capped or not, would miss",
                       description="For each R and neighbour cap N: the share of next-frame contacts (a moving "
                                   "receiver, a sender touching it one frame later) whose sender is R or farther "
                                   "away, or not among the receiver's N nearest, in the frame the graph is built "
                                   "on; and the senders per receiver the graph keeps. The contact-miss rate that "
                                   "chooses R and max_neighbours (docs/surrogate.md, Neighbour cap).")
    p.add_argument("--splits", type=Path, required=True, help="a dataset's splits.csv (id, split, path)")
    p.add_argument("--split", default="train", help="the split to count (default: train)")
    p.add_argument("--radius", type=float, nargs="+", required=True, metavar="R", help="connectivity radii (m)")
    p.add_argument("--cap", type=int, nargs="*", metavar="N",
                   help="neighbour caps (senders per receiver, at most 64); no cap is always a row")
    p.add_argument("--sims", type=int, help="only the split's first N sims")
    p.add_argument("--out", type=Path, help="also write the table as CSV")
    p.set_defaults(func=cmd_contacts)

    p = sub.add_parser("train", help="train Graph-DEM (resumes an interrupted run in the same folder)",
                       description="Train the Graph-DEM surrogate on the train split and keep the checkpoint "
                                   "with the lowest validation rollout MSE. Writes best.pt, last.pt (full state, "
                                   "used to resume) and history.csv into --out-dir. The model and training "
                                   "settings are the --scene's section of the workflow's config: the package "
                                   "defaults, --config files and --set keys, e.g. graphdem train --scene slide "
                                   "--set scale=ci --set slide.train.lr=1e-3 (graphdem config prints the result).",
                       epilog="Paths default to the workflow's: results/<scene>/dataset/{stats.json,splits.csv} "
                              "and results/<scene>/model/.")
    p.add_argument("--scene", choices=names + sorted(gcli.gconfig.BENCHMARKS),
                   help="the scene or public benchmark whose model and train sections to use")
    gcli.config_options(p)
    p.add_argument("--stats", type=Path, help="dataset stats.json (default results/<scene>/dataset/stats.json)")
    p.add_argument("--splits", type=Path, help="dataset splits.csv (default results/<scene>/dataset/splits.csv)")
    p.add_argument("--out-dir", type=Path, help="checkpoint folder (default results/<scene>/model)")
    # the workflow passes its already resolved sections (internal; users give --scene/--config/--set)
    p.add_argument("--model-json", type=_json, help=argparse.SUPPRESS)
    p.add_argument("--train-json", type=_json, help=argparse.SUPPRESS)
    p.add_argument("--threads", type=int, default=1,
                   help="torch CPU threads (under torchrun shared by the node's processes)")
    _device(p, None)
    p.add_argument("--fresh", action="store_true", help="ignore an unfinished last.pt and start over")
    p.add_argument("--max-steps", type=int, help="stop after this many steps, leaving a resumable last.pt")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("rollout", help="predict every frame after the first K of each sim; write H5MD",
                       description="Roll the checkpoint's model out on H5MD sims: the first K frames come "
                                   "from the data, every later frame is predicted; kinematic particles follow "
                                   "the data. Writes <out-dir>/<sim>.h5 in the sims' layout. Several "
                                   "--checkpoint: their ensemble (the mean acceleration of the models).")
    _checkpoint_and_data(p, ensemble=True)
    p.add_argument("--out-dir", type=Path, required=True)
    p.set_defaults(func=cmd_rollout)

    p = sub.add_parser("evaluate", help="rollout MSE and scene metrics of a checkpoint on H5MD sims",
                       description="Evaluate a checkpoint on every H5MD sim in --data (all of them as test): "
                                   "rollout MSE per sim and overall, and the scene's metrics (docs/surrogate.md) "
                                   "where the scene is known, beside a constant-velocity baseline and, with "
                                   "--ensemble, the DEM ensemble (the DEM's own chaos). Acc is the article's, of "
                                   "the test-set mean curve (acc_percent), beside the pooled one "
                                   "(acc_pooled_percent). The sims are --data, or one split of a --splits table. "
                                   "Several --checkpoint: their ensemble is scored as Graph-DEM.")
    _checkpoint_and_data(p, data_required=False, ensemble=True)
    p.add_argument("--splits", type=Path, help="a split table (id, split, path); evaluates the sims of --split")
    p.add_argument("--split", choices=("auto", "test", "valid"), default="test",
                   help="which split the sims are (with --data) or which to take from --splits; auto: test where "
                        "the table has one, else valid (said in every output)")
    p.add_argument("--history", type=int, nargs="+", required=True,
                   help="K of each protocol: frames given from the data and not scored; at least the history "
                        "length the checkpoint reads (more: each step still reads its last frames). Several K: "
                        "one table with a row set per K (the history column), plots of all, the GIF of the first")
    p.add_argument("--out", type=Path, required=True, help="metrics CSV to write")
    p.add_argument("--per-step", type=Path, help="per-step CSV (truth and prediction per metric and frame)")
    p.add_argument("--table-html", type=Path,
                   help="metrics CSV as an HTML table whose empty cells say n/a or undefined and why (the report's)")
    p.add_argument("--rollouts", type=Path, help="folder of rollouts made by this checkpoint (else roll out now)")
    p.add_argument("--ensemble", type=Path, nargs="+",
                   help="the DEM ensemble's member folders, <sim id>.h5 per sim in each: the sim rerun by its engine "
                        "from its own state at the last given frame, perturbed; scored member by member (method "
                        "dem_ensemble) and as the members' mean (dem_ensemble_mean), and their spread is the unit "
                        "of every method's error_in_spreads")
    p.add_argument("--intervals-json", type=json.loads, default=None,
                   help='the bootstrap of every figure\'s interval, {"samples": N, "level": L, "seed": S} (default: '
                        "the config's intervals)")
    _body_displacement(p)
    p.add_argument("--plots", type=Path, help="folder for metrics_over_frames.png and rollout.gif")
    p.add_argument("--animate", help="sim id to animate (default: the first)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("combine", help="stack CSV tables of the same columns (e.g. one per protocol)")
    p.add_argument("--tables", type=Path, nargs="+", required=True)
    p.add_argument("--union", action="store_true", help="tables may have different columns (blank where missing)")
    p.add_argument("--out", type=Path, required=True)
    p.set_defaults(func=cmd_combine)

    p = sub.add_parser("seeds", help="mean and spread of every metric over models trained with different seeds",
                       description="Combine the metrics.csv of models trained with different seeds (the same data, "
                                   "the same evaluation) into one table: per method, metric, protocol and value "
                                   "column the mean, sample standard deviation, range and each seed's value "
                                   "(docs/surrogate.md, Seeds).")
    p.add_argument("--metrics", type=Path, nargs="+", required=True, help="one metrics.csv per seed")
    p.add_argument("--seeds", type=int, nargs="+", required=True, help="the seed of each table, in the same order")
    p.add_argument("--out", type=Path, required=True)
    p.set_defaults(func=cmd_seeds)

    from surrogate import devices
    p = sub.add_parser(
        "card", help="a public benchmark's card: Graph-DEM and constant velocity over seeds, beside the article",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="The benchmark card of a public benchmark (docs/benchmarks.md, Benchmark card). From the\n"
                    "evaluation of each model trained with a different seed: per method, protocol K and quantity\n"
                    "the mean, sample standard deviation (ddof 1), smallest and largest value over the seeds and\n"
                    "each seed's value (--out, CSV), and a short table to read (--markdown) that also states the\n"
                    "split scored, the hardware and the article's figures beside ours.\n\n"
                    "quantities (per seed first, then over the seeds; NaN is never skipped):\n"
                    "  rollout_mse           rollout MSE (m^2) of metrics.csv\n"
                    "  mse_first_frame       MSE (m^2) at the first predicted frame, mean over sims (--steps)\n"
                    "  mse_last_frame        MSE (m^2) at the last predicted frame, mean over sims (--steps)\n"
                    "  rmse_diameters        sqrt(rollout MSE) / d, d = the moving particles' mean diameter\n"
                    "                        (2 x the mean radius of --stats, the train split's moving particles)\n"
                    "  blown_up              rollouts that blew up (n_blown_up); total: over all seeds\n"
                    "  rollout_ms_per_frame  Graph-DEM's rollout wall time per predicted frame (ms)\n"
                    "  train_seconds         training wall time per model (history.csv's seconds)\n"
                    "  train_cost            each epoch's seconds x its threads x processes (CPU: core-hours)\n"
                    "                        or x its processes (GPU: GPU-hours), summed, per model\n\n"
                    "seed ensemble (--ensemble-metrics, --ensemble-steps): the seeds' models as one simulator that\n"
                    "integrates their mean acceleration, scored once (method seed_ensemble, no spread); its\n"
                    "training is every model's, summed",
        epilog="The workflow makes it (B: slide_samer or slide_small; the seeds: the config key seeds):\n"
               "  snakemake -c2 results/<B>/card.md --config solidgn_root=/path/to/solidgn")
    p.add_argument("--benchmark", choices=sorted(gcli.gconfig.BENCHMARKS), required=True,
                   help="the public benchmark (its name in the card)")
    p.add_argument("--seeds", type=int, nargs="+", required=True, help="the training seeds, one per model")
    p.add_argument("--metrics", type=Path, nargs="+", required=True,
                   help="each seed's metrics.csv (graphdem evaluate --out), in --seeds order")
    p.add_argument("--steps", type=Path, nargs="+", required=True,
                   help="each seed's per-step table (graphdem evaluate --per-step), in --seeds order")
    p.add_argument("--histories", type=Path, nargs="+", required=True,
                   help="each seed's model/history.csv (graphdem train), in --seeds order")
    p.add_argument("--stats", type=Path, required=True, help="the dataset's stats.json (the mean particle radius)")
    p.add_argument("--ensemble-metrics", type=Path,
                   help="the seed ensemble's metrics.csv (graphdem evaluate with every seed's --checkpoint): its "
                        "rows join the card as seed_ensemble, costed as all its models")
    p.add_argument("--ensemble-steps", type=Path, help="the seed ensemble's per-step table (with --ensemble-metrics)")
    p.add_argument("--article-json", type=_json, required=True,
                   help='the article\'s figures, the config\'s B.article: {"history": K, "split": "test", '
                        '"rollout_mse": {"graphdem": ..., "gns": ...}}')
    p.add_argument("--device", type=_device_arg, default="auto",
                   help=f"the device setting the jobs were given ({devices.CHOICES}); said on the card, and "
                        "where a model trained with --train-threads")
    p.add_argument("--train-threads", type=int,
                   help="torch threads a model trained on (one process, on --device), for a history.csv that does "
                        "not record where it ran (written before it had the threads and device columns); default: "
                        "refuse such a file")
    p.add_argument("--out", type=Path, required=True, help="card.csv to write")
    p.add_argument("--markdown", type=Path, required=True, help="card.md to write")
    p.set_defaults(func=cmd_card)

    p = sub.add_parser("property-test", help="the property-sensitivity test (article Fig. 14) of a checkpoint",
                       description="For each test sim, two DEM reruns that differ only in one node property (low, "
                                   "high) and the checkpoint's rollouts of both: the change of the moving particles' "
                                   "mean x at the last frame, DEM against Graph-DEM, same sign and ratio, beside the "
                                   "DEM's own chaos (docs/surrogate.md, Property test).")
    p.add_argument("--checkpoint", type=Path, required=True, help="the model that made the rollouts (best.pt)")
    p.add_argument("--runs", type=Path, nargs=2, required=True, metavar=("LOW", "HIGH"),
                   help="the low and the high value's run folders, each with sims/<id>.h5 and rollouts/<id>.h5")
    p.add_argument("--sims", nargs="+", required=True, metavar="ID", help="the test sims' ids")
    p.add_argument("--property", required=True, help="the node property the runs differ in (e.g. young)")
    p.add_argument("--history", type=int, required=True, help="K, the frames each rollout was given")
    p.add_argument("--tolerance", type=float, default=0.25,
                   help="a sim passes when Graph-DEM's change has the DEM's sign and is within this fraction of it")
    p.add_argument("--sims-dir", type=Path, help="the scene's sims folder (with --ensemble: the chaos of each sim)")
    p.add_argument("--ensemble", type=Path, help="the DEM ensemble's sims folder: each sim rerun from a perturbed "
                                                 "packing; its change of mean x is the chaos the signal stands beside")
    p.add_argument("--out", type=Path, required=True, help="CSV: one row per sim, then 'all'")
    p.add_argument("--plot", type=Path, help="PNG: Fig. 14's overlay of the first sim and the changes per sim")
    p.add_argument("--title", help="the plot's title")
    p.set_defaults(func=cmd_property_test)

    p = sub.add_parser("stress-readout", help="train the shear-stress readout on a shear dataset's DEM frames",
                       description="Fit the pair-force readout of the shear stress (surrogate/stress.py; "
                                   "docs/shear-scene.md) to the train split's shear_stress observable, keeping the "
                                   "epoch with the lowest valid error of tau / sigma_n.")
    p.add_argument("--splits", type=Path, required=True, help="the dataset's splits.csv (train and valid sims)")
    p.add_argument("--settings-json", type=_json, required=True,
                   help="the scene's stress_readout settings: cutoff, hidden, layers, epochs, lr, seed")
    p.add_argument("--out", type=Path, required=True, help="the readout to write (.pt: tensors and JSON)")
    p.add_argument("--history", type=Path, required=True, help="CSV: train and valid MSE per epoch")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads (default 1)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_stress_readout)

    p = sub.add_parser("stress-test", help="the predicted against the DEM's peak shear stress of the test sims",
                       description="Read the shear stress from the DEM's frames, Graph-DEM's rollouts and constant "
                                   "velocity with the readout, beside the DEM's observable and its ensemble rerun's; "
                                   "peak and curve errors per sim (surrogate/stress_test.py).")
    p.add_argument("--readout", type=Path, required=True, help="the readout (graphdem stress-readout)")
    p.add_argument("--checkpoint", type=Path, required=True, help="the model that made the rollouts (best.pt)")
    p.add_argument("--sims", type=Path, nargs="+", required=True, help="the test sims' H5MD files")
    p.add_argument("--rollouts", type=Path, required=True, help="the folder of the rollouts, <id>.h5")
    p.add_argument("--ensemble", type=Path, help="the DEM ensemble's folder, <id>.h5 (its observable: the chaos)")
    p.add_argument("--history", type=int, required=True, help="K, the frames each rollout was given")
    p.add_argument("--tolerance", type=float, required=True,
                   help="a sim passes when Graph-DEM's peak is within this fraction of the DEM's")
    p.add_argument("--out", type=Path, required=True, help="CSV: one row per sim, then 'all'")
    p.add_argument("--plot", type=Path, help="PNG: the stress curves per sim")
    p.add_argument("--title", help="the plot's title")
    p.set_defaults(func=cmd_stress_test)

    p = sub.add_parser("stability-surrogate", help="long and perturbed rollouts, and precision, of a checkpoint",
                       description="Stress test of the surrogate on H5MD sims: rollouts --lengths times the "
                                   "recorded window from a history with random-walk noise (non-finite frames, "
                                   "escapes or particles put back into the box, the overlap distribution and "
                                   "kinetic energy per frame, the first frame outside the physical envelope, error "
                                   "growth per step, final speed), and the recorded rollout in float64, float32 and "
                                   "bfloat16 (differences from float64).")
    _checkpoint_and_data(p)
    p.add_argument("--lengths", type=int, nargs="+", required=True, help="rollout lengths in recorded windows")
    p.add_argument("--noise", type=float, required=True, help="std (m per frame) of the initial history's noise")
    p.add_argument("--seed", type=int, required=True, help="seed of the history noise")
    p.add_argument("--max-overlap", type=float, required=True, help="overlap limit (fraction of the smaller radius)")
    p.add_argument("--energy-envelope", type=float, default=float("inf"),
                   help="a frame whose kinetic energy exceeds this multiple of the data's peak leaves the physical "
                        "envelope (default: no energy limit)")
    p.add_argument("--out", type=Path, required=True, help="CSV report")
    p.add_argument("--frames-out", type=Path, help="CSV: per frame of each long rollout (energy, overlaps, outside)")
    p.add_argument("--plot", type=Path, help="PNG: kinetic energy and overlaps per frame of the long rollouts")
    p.add_argument("--title", help="the plot's title")
    p.set_defaults(func=cmd_stability_surrogate)

    p = sub.add_parser("performance-dem", help="time and score one DEM contender (time step, stiffness, cores)",
                       description="Rerun the DEM on the sims of --sims (their settled packings) with the changes "
                                   "of --variant (dt_safety, dt_factor, stiffness_factor, ranks, threads), --repeats "
                                   "times each; time the recorded window (the engine's own loop time; run-up and "
                                   "start-up in their own columns) and score against --truth. One CSV row.")
    p.add_argument("--scene", choices=names, required=True)
    p.add_argument("--name", required=True, help="the contender's name")
    p.add_argument("--variant", type=_json, required=True, help='changes, e.g. {"dt_safety": 0.1, "ranks": 2}')
    p.add_argument("--sims", type=_json, required=True, help="the sims' sweep rows (JSON list)")
    p.add_argument("--packings", type=Path, required=True, help="folder of the settled packings")
    p.add_argument("--truth", type=Path, nargs="+", required=True, help="the sims' H5MD files, in --sims order")
    p.add_argument("--history", type=int, required=True, help="K: frames not scored (the surrogate's input)")
    p.add_argument("--repeats", type=int, required=True)
    _body_displacement(p)
    p.add_argument("--out", type=Path, required=True)
    p.set_defaults(func=cmd_performance_dem)

    p = sub.add_parser("performance-surrogate", help="time and score one surrogate contender",
                       description="Roll the checkpoint out on --data with the runtime switches of --runtime-json "
                                   "changed by --variant (and, with latent/hidden/message_passing in it, an "
                                   "untrained model of that size, timed only): one warm-up, then the median of "
                                   "--repeats. One CSV row.")
    _checkpoint_and_data(p)
    p.add_argument("--name", required=True, help="the contender's name")
    p.add_argument("--variant", type=_json, required=True, help='changes, e.g. {"precision": "bfloat16"}')
    p.add_argument("--repeats", type=int, required=True)
    _body_displacement(p)
    p.add_argument("--out", type=Path, required=True)
    p.set_defaults(func=cmd_performance_surrogate)

    p = sub.add_parser("performance-report", help="benchmark.csv and the Pareto plot from the contenders' rows")
    p.add_argument("--tables", type=Path, nargs="+", required=True, help="one CSV per contender")
    p.add_argument("--main", required=True, help="the surrogate contender of the headline figures")
    p.add_argument("--reference", required=True, help="the DEM reference contender")
    p.add_argument("--packings", type=Path, nargs="*", help="packing folders (their settling time is reported)")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--plot", type=Path, required=True)
    p.add_argument("--substeps-plot", type=Path, help="the speed-up against DEM sub-steps per frame (PNG)")
    p.add_argument("--title", default="run time against error")
    p.set_defaults(func=cmd_performance_report)

    from surrogate import doc_tables
    doc_tables.add_command(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    from surrogate.errors import CheckpointError, TrainingDiverged

    args = build_parser().parse_args(argv)
    gcli.check_outputs(args)
    try:
        args.func(args)
    except (*gcli.errors(), CheckpointError, TrainingDiverged) as exc:
        print(f"graphdem {args.command}: error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
