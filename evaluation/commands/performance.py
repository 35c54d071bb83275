"""The performance stage's subcommands (run time against error, evaluation/performance.py): `graphdem
performance-dem` and `performance-surrogate` time and score one contender each, `performance-report` ranks them."""

from __future__ import annotations

import json
from pathlib import Path

from evaluation.commands import metric_options
from generators import cli as gcli
from generators import scenes
from generators.cli_paths import input_path, output_file
from surrogate.commands import options


def register(sub) -> None:
    p = gcli.add_command(sub, "performance-dem", run_dem,
                         help="time and score one DEM contender (time step, stiffness, cores)")
    p.add_argument("--scene", choices=scenes.names(), required=True)
    p.add_argument("--name", required=True, help="the contender's name")
    p.add_argument("--variant", type=options.json_arg, required=True,
                   help='changes, e.g. {"dt_safety": 0.1, "ranks": 2}')
    p.add_argument("--sims", type=options.json_arg, required=True, help="the sims' sweep rows (JSON list)")
    p.add_argument("--packings", type=input_path, required=True, help="folder of the settled packings")
    p.add_argument("--truth", type=input_path, nargs="+", required=True, help="the sims' H5MD files, in --sims order")
    p.add_argument("--history", type=int, required=True, help="K: frames not scored (the surrogate's input)")
    p.add_argument("--repeats", type=int, required=True)
    metric_options.scene_metric_options(p)
    p.add_argument("--out", type=output_file, required=True)

    p = gcli.add_command(sub, "performance-surrogate", run_surrogate, help="time and score one surrogate contender")
    options.checkpoint_and_data(p)
    p.add_argument("--name", required=True, help="the contender's name")
    p.add_argument("--variant", type=options.json_arg, required=True, help='changes, e.g. {"precision": "bfloat16"}')
    p.add_argument("--repeats", type=int, required=True)
    metric_options.scene_metric_options(p)
    p.add_argument("--out", type=output_file, required=True)

    p = gcli.add_command(sub, "performance-report", run_report,
                         help="performance.csv and the Pareto plot from the contenders' rows")
    p.add_argument("--tables", type=input_path, nargs="+", required=True, help="one CSV per contender")
    p.add_argument("--main", required=True, help="the surrogate contender of the headline figures")
    p.add_argument("--reference", required=True, help="the DEM reference contender")
    p.add_argument("--packings", type=input_path, nargs="*", help="packing folders (their settling time is reported)")
    p.add_argument("--out", type=output_file, required=True)
    p.add_argument("--plot", type=output_file, required=True)
    p.add_argument("--substeps-plot", type=output_file, help="the speed-up against DEM sub-steps per frame (PNG)")
    p.add_argument("--map", type=output_file, help="where the surrogate pays, per test sim (CSV; "
                                                   "evaluation/performance_map.py)")
    p.add_argument("--map-plot", type=output_file, help="the map's plot: speed-up per sim against its DEM sub-steps")
    p.add_argument("--title", default="run time against error")

    p = gcli.add_command(sub, "performance-pays", run_pays,
                         help="one row per scene: does the surrogate pay, by how much, and why (from the maps)")
    p.add_argument("--maps", type=input_path, nargs="+", required=True,
                   help="results/<scene>/performance_map.csv files (the scene is the folder's name)")
    p.add_argument("--out", type=output_file, required=True)


def run_dem(args) -> None:
    """Rerun the DEM on the sims of --sims (their settled packings) with the changes of --variant (dt_safety,
    dt_factor, stiffness_factor, ranks, threads), --repeats times each; time the recorded window (the engine's own
    loop time; run-up and start-up in their own columns) and score against --truth. One CSV row."""
    from evaluation import performance
    rows = args.sims
    packings = [Path(args.packings) / row["packing"] for row in rows]
    result = performance.dem_contender(args.name, args.variant, args.scene, rows, packings, args.truth, args.history,
                                       args.repeats, args.body_displacement, frames=args.frames)
    options.write_rows([result], args.out)
    print(json.dumps(result, indent=1, default=str))


def run_surrogate(args) -> None:
    """Roll the checkpoint out on --data with the runtime switches of --runtime-json changed by --variant (and, with
    latent/hidden/message_passing in it, an untrained model of that size, timed only): one warm-up, then the median
    of --repeats. One CSV row."""
    from evaluation import performance
    result = performance.surrogate_contender(args.name, args.variant, args.checkpoint,
                                             options.runtime_config(args, required_by="performance-surrogate"),
                                             args.data, args.repeats, args.threads,
                                             body_displacement=args.body_displacement, frames=args.frames,
                                             device=args.device)
    options.write_rows([result], args.out)
    print(json.dumps(result, indent=1, default=str))


def run_report(args) -> None:
    import numpy as np
    import pandas as pd

    from evaluation import performance, plots
    from evaluation import tables as tables_csv
    from generators import record
    contenders = pd.concat([tables_csv.read_csv(p) for p in args.tables], ignore_index=True)
    settling = [record.read(p).run.wall_time for p in args.packings or []]
    table = performance.report(contenders, args.main, args.reference, float(np.mean(settling)) if settling else None)
    options.write_table(table, args.out)
    plots.pareto(table, args.plot, args.title)
    if args.substeps_plot:
        plots.speedup_substeps(table, args.main, args.substeps_plot, f"{args.title}: speed-up against DEM sub-steps")
    if args.map:
        from evaluation import performance_map
        sims = performance_map.sim_map(table, args.main, args.reference)
        options.write_table(sims, args.map)
        if args.map_plot:
            plots.performance_map(sims, args.map_plot, f"{args.title}: where the surrogate pays, per test sim")
    main = table[table["main"].astype(bool)].iloc[0]
    matched = (f"{main['speedup_vs_matched_dem']:.2f}x faster than {main['matched_dem']} (the fastest DEM at least as "
               f"accurate on the MSE and every scene metric)" if main["matched_dem"] else
               "no DEM contender is as accurate on the MSE and every scene metric")
    print(f"{args.out}: {len(table)} rows; {main['contender']}: {main['seconds_per_frame'] * 1000:.2f} ms per frame, "
          f"{main['speedup_vs_reference']:.1f}x faster than the DEM reference, {matched}, break-even at "
          f"{main['break_even_substeps']:.0f} DEM sub-steps per frame")


def run_pays(args) -> None:
    """The pays table of the README (evaluation/performance_map.py, ``pays_table``): per scene, the median speed-up
    over its test sims against the closest DEM comparison its map has, its range, the DEM sub-steps per frame
    against the break-even, and the verdict."""
    from evaluation import performance_map
    from evaluation import tables as tables_csv
    table = performance_map.pays_table({Path(p).parent.name: tables_csv.read_csv(p) for p in args.maps})
    options.write_table(table, args.out)
    for row in table.to_dict("records"):
        print(f"{row['scene']}: {row['verdict']}, {row['speedup']:.3g}x (median over {row['sims']} sims) against "
              f"{row['dem_contender']} ({row['match']}); {row['dem_steps_per_frame']:.0f} DEM sub-steps per frame, "
              f"break-even {row['break_even_steps']:.0f}")
