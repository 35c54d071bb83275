"""`graphdem train`: train Graph-DEM with the model and train sections of a scene's config (surrogate/train.py)."""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from generators import cli as gcli
from generators import scenes
from generators.cli_paths import input_path, output_folder, split_table
from surrogate.commands import options


def register(sub) -> None:
    p = gcli.add_command(sub, "train", run, help="train Graph-DEM (resumes an interrupted run in the same folder)",
                         epilog="Paths default to the workflow's: results/<name>/dataset/{stats.json,splits.csv} "
                                "and results/<name>/model/, <name> the scene or public benchmark, or the "
                                "--user-data folder's name.")
    options.scene_or_benchmark(p, False, "whose model and train sections to use",
                               user_data="a folder of H5MD sims of your own (docs/user-data.md): train with the "
                                         "config's user section")
    gcli.config_options(p)
    p.add_argument("--stats", type=input_path, help="dataset stats.json (default results/<name>/dataset/stats.json)")
    p.add_argument("--splits", type=split_table, help="dataset splits.csv (default results/<name>/dataset/splits.csv)")
    p.add_argument("--out-dir", type=output_folder, help="checkpoint folder (default results/<name>/model)")
    # the workflow passes its already resolved sections (internal; users give --scene or --benchmark, --config, --set)
    p.add_argument("--model-json", type=options.json_arg, help=argparse.SUPPRESS)
    p.add_argument("--train-json", type=options.json_arg, help=argparse.SUPPRESS)
    p.add_argument("--threads", type=int, default=1,
                   help="torch CPU threads (under torchrun shared by the node's processes)")
    options.device_option(p, None)
    p.add_argument("--fresh", action="store_true", help="ignore an unfinished last.pt and start over")
    p.add_argument("--max-steps", type=int, help="stop after this many steps, leaving a resumable last.pt")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(complete=default_paths)


def default_paths(args) -> None:
    """Fill --stats, --splits and --out-dir left out with the workflow's paths of --scene, --benchmark or --user-data
    (named by its folder), so that `graphdem` checks them against each other before training starts, as it checks
    paths given."""
    name = _results_name(args)
    if not name:
        return
    where = Path("results") / name
    for dest, default in (("stats", "dataset/stats.json"), ("splits", "dataset/splits.csv"), ("out_dir", "model")):
        if getattr(args, dest) is None:
            setattr(args, dest, where / default)


def _results_name(args) -> str | None:
    """The results folder's name of --scene or --benchmark, or of --user-data (the folder's basename)."""
    if getattr(args, "user_data", None) is not None:
        return Path(os.path.abspath(args.user_data)).name
    return args.name


def run(args) -> None:
    """Train the Graph-DEM surrogate on the train split and keep the checkpoint with the lowest validation rollout
    MSE. Writes best.pt, last.pt (full state, used to resume) and history.csv into --out-dir. The model and training
    settings are the section of the --scene or --benchmark in the workflow's config (with --user-data, its user
    section): the package defaults, --config files and --set keys, e.g. graphdem train --scene slide --set scale=ci
    --set slide.train.lr=1e-3 (graphdem config prints the result)."""
    from surrogate import distributed, train
    model, train_cfg, device, stats, splits, out_dir = sections(args)
    main = distributed.World.from_env().main
    options.log_to_stderr(quiet=not main)
    state = train.train(stats, splits, model, train_cfg, out_dir,
                        threads=args.threads, fresh=args.fresh, max_steps=args.max_steps,
                        progress=not args.no_progress, device=device)
    if main:
        print(json.dumps({k: state[k] for k in ("epoch", "step", "best_epoch", "best_mse", "finished", "seconds")}))


def sections(args) -> tuple[dict, dict, str, Path, Path, Path]:
    """The model and train config, the device, and the stats, splits and output folder, of ``graphdem train``:
    from the resolved config's section of --scene or --benchmark (the workflow's keys), or from the rule's resolved
    sections.
    --device wins over the config's ``device``; without either, auto."""
    if args.model_json is not None or args.train_json is not None:
        if args.model_json is None or args.train_json is None or _results_name(args) or args.config_file or args.set:
            raise SystemExit("graphdem train: --model-json and --train-json (the workflow's resolved sections) go "
                             "together and replace --scene, --benchmark or --user-data, --config and --set")
        model, train_cfg, where, device = args.model_json, args.train_json, None, args.device or "auto"
    else:
        name = _results_name(args)
        if not name:
            raise SystemExit(f"graphdem train: give --scene (one of {', '.join(scenes.names())}), --benchmark "
                             f"(one of {', '.join(sorted(gcli.gconfig.BENCHMARKS))}) or --user-data FOLDER to train "
                             "with its model and train config")
        resolved = gcli.resolved_config(args)
        section = resolved["user" if args.name is None else args.name]
        model, train_cfg, where = section["model"], section["train"], Path("results") / name
        device = args.device or resolved["device"]
    paths = []
    for value, default in ((args.stats, "dataset/stats.json"), (args.splits, "dataset/splits.csv"),
                           (args.out_dir, "model")):
        if value is None and where is None:
            raise SystemExit("graphdem train: --stats, --splits and --out-dir are needed with --model-json")
        paths.append(Path(value) if value is not None else where / default)
    return model, train_cfg, device, *paths
