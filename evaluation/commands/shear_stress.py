"""`graphdem shear-stress-readout` (train the shear-stress readout on a shear dataset's DEM frames,
evaluation/shear_stress.py) and `graphdem shear-stress-check` (the predicted against the DEM's peak shear stress,
evaluation/shear_stress_check.py)."""

from __future__ import annotations

from generators import cli as gcli
from generators.cli_paths import input_path, output_file, split_table
from surrogate.commands import options


def register(sub) -> None:
    p = gcli.add_command(sub, "shear-stress-readout", run_readout,
                         help="train the shear-stress readout on a shear dataset's DEM frames")
    p.add_argument("--splits", type=split_table, required=True, help="the dataset's splits.csv (train and valid sims)")
    p.add_argument("--settings-json", type=options.json_arg, required=True,
                   help="the scene's shear_stress_readout settings: cutoff, hidden, layers, epochs, lr, seed")
    p.add_argument("--out", type=output_file, required=True, help="the readout to write (.pt: tensors and JSON)")
    p.add_argument("--history", type=output_file, required=True, help="CSV: train and valid MSE per epoch")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads (default 1)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")

    p = gcli.add_command(sub, "shear-stress-check", run_test,
                         help="the predicted against the DEM's peak shear stress of the test sims")
    p.add_argument("--readout", type=input_path, required=True, help="the readout (graphdem shear-stress-readout)")
    p.add_argument("--checkpoint", type=input_path, required=True, help="the model that made the rollouts (best.pt)")
    p.add_argument("--sims", type=input_path, nargs="+", required=True, help="the test sims' H5MD files")
    p.add_argument("--rollouts", type=input_path, required=True, help="the folder of the rollouts, <id>.h5")
    p.add_argument("--ensemble", type=input_path, help="the DEM ensemble's folder, <id>.h5 (its observable: the chaos)")
    p.add_argument("--runtime-json", type=options.json_arg,
                   help="the runtime switches the rollouts were made with (the scene's runtime section): constant "
                        "velocity runs under them too; default: plain extrapolation")
    p.add_argument("--history", type=int, required=True, help="K, the frames each rollout was given")
    p.add_argument("--tolerance", type=float, required=True,
                   help="a sim passes when Graph-DEM's peak is within this fraction of the DEM's")
    p.add_argument("--out", type=output_file, required=True, help="CSV: one row per sim, then 'all'")
    p.add_argument("--plot", type=output_file, help="PNG: the stress curves per sim")
    p.add_argument("--title", help="the plot's title")


def run_readout(args) -> None:
    """Fit the pair-force readout of the shear stress (evaluation/shear_stress.py; docs/shear-scene.md) to the train
    split's shear_stress observable, keeping the epoch with the lowest valid error of tau / sigma_n."""
    import pandas as pd

    from evaluation import shear_stress
    from generators import h5md
    options.log_to_stderr()
    splits = pd.read_csv(args.splits)
    samples = {split: [shear_stress.Sample.from_trajectory(h5md.read(p))
                       for p in splits.loc[splits["split"] == split, "path"]]
               for split in ("train", "valid")}
    model, meta, history = shear_stress.fit(samples["train"], samples["valid"], args.settings_json,
                                            progress=not args.no_progress, threads=args.threads)
    options.write_table(history, args.history)
    shear_stress.save(args.out, model, meta)
    print(f"stress readout: valid MSE of tau / sigma_n {meta['valid_mse']:.4g} (epoch {meta['epoch']}), "
          f"{len(meta['train_sims'])} train and {len(meta['valid_sims'])} valid sims")


def run_test(args) -> None:
    """Read the shear stress from the DEM's frames, Graph-DEM's rollouts and constant velocity with the readout, beside
    the DEM's observable and its ensemble rerun's; peak and curve errors per sim (evaluation/shear_stress_check.py).
    """
    from evaluation import plots, shear_stress_check
    from evaluation.baseline import Extrapolation
    from surrogate import provenance
    table, curves = shear_stress_check.run(args.readout, args.sims, args.rollouts, provenance.digest(args.checkpoint),
                                           args.history, args.tolerance, args.ensemble,
                                           Extrapolation.of(args.checkpoint, args.runtime_json))
    if args.plot:
        plots.stress_curves(curves, table, args.history, args.plot, args.title or "shear stress")
    options.write_table(table, args.out)
    print(table.to_string(index=False))
