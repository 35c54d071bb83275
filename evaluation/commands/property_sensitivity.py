"""`graphdem property-sensitivity`: the property-sensitivity test (article Fig. 14) of a checkpoint
(evaluation/property_sensitivity.py)."""

from __future__ import annotations

from generators import cli as gcli
from generators.cli_paths import input_path, output_file
from surrogate.commands import options


def register(sub) -> None:
    p = gcli.add_command(sub, "property-sensitivity", run,
                         help="the property-sensitivity test (article Fig. 14) of a checkpoint")
    p.add_argument("--checkpoint", type=input_path, required=True, help="the model that made the rollouts (best.pt)")
    p.add_argument("--runs", type=input_path, nargs=2, required=True, metavar=("LOW", "HIGH"),
                   help="the low and the high value's run folders, each with sims/<id>.h5 and rollouts/<id>.h5")
    p.add_argument("--sims", nargs="+", required=True, metavar="ID", help="the test sims' ids")
    p.add_argument("--property", required=True, help="the node property the runs differ in (e.g. young)")
    p.add_argument("--history", type=int, required=True, help="K, the frames each rollout was given")
    p.add_argument("--tolerance", type=float, default=0.25,
                   help="a sim passes when Graph-DEM's change has the DEM's sign and is within this fraction of it")
    p.add_argument("--sims-dir", type=input_path,
                   help="the scene's sims folder (with --ensemble: the chaos of each sim)")
    p.add_argument("--ensemble", type=input_path,
                   help="a DEM ensemble member's sims folder: each sim rerun from its state at the last given frame, "
                        "perturbed; its change of mean x is the chaos the signal stands beside")
    p.add_argument("--runtime-json", type=options.json_arg,
                   help="the runtime switches the rollouts were made with (the scene's runtime section): constant "
                        "velocity runs under them too; default: plain extrapolation")
    p.add_argument("--out", type=output_file, required=True, help="CSV: one row per sim, then 'all'")
    p.add_argument("--plot", type=output_file, help="PNG: Fig. 14's overlay of the first sim and the changes per sim")
    p.add_argument("--title", help="the plot's title")


def run(args) -> None:
    """For each test sim, two DEM reruns that differ only in one node property (low, high) and the checkpoint's
    rollouts of both: the change of the moving particles' mean x at the last frame, DEM against Graph-DEM, same sign
    and ratio, beside the DEM's own chaos (docs/surrogate.md, Property sensitivity)."""
    from evaluation import plots, property_sensitivity
    from evaluation.baseline import Extrapolation
    from surrogate import provenance
    if (args.ensemble is None) != (args.sims_dir is None):
        raise SystemExit("graphdem property-sensitivity: give --sims-dir and --ensemble together (the sims and their "
                         "DEM ensemble reruns), or neither")
    chaos = (args.sims_dir, args.ensemble) if args.ensemble is not None else None
    table, pairs = property_sensitivity.run(tuple(args.runs), args.sims, args.property,
                                            provenance.digest(args.checkpoint), args.history, args.tolerance, chaos,
                                            Extrapolation.of(args.checkpoint, args.runtime_json))
    if args.plot:
        plots.property_sensitivity(pairs, table, args.plot, args.title or f"property sensitivity: {args.property}")
    options.write_table(table, args.out)
    print(table.to_string(index=False))
