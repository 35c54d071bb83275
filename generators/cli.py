"""`graphdem`: the command line of the pipeline; each Snakemake rule calls one subcommand.

Every subcommand writes its outputs atomically and exits non-zero with a one-line reason
(naming the file, sim, frame or config key) when something is wrong.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from generators import config as gconfig

SCENES = ("slide",)


def _json(text: str) -> dict:
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not valid JSON: {exc}") from exc


def cmd_config(args) -> None:
    import yaml
    overrides = {}
    for item in args.set or []:
        key, _, value = item.partition("=")
        node = overrides
        *parents, leaf = key.split(".")
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = yaml.safe_load(value)
    print(yaml.safe_dump(gconfig.load(overrides), sort_keys=False))


def cmd_sweep(args) -> None:
    from generators import sweep
    from generators.atomic import atomic_path
    table = sweep.build(args.scene, args.config_json)
    with atomic_path(args.out) as tmp:
        table.to_csv(tmp, index=False)
    print(f"{args.out}: {len(table)} simulations, splits {table['split'].value_counts().to_dict()}")


def cmd_prepare(args) -> None:
    from generators.lammps import slide as lammps_slide
    meta = lammps_slide.settle(args.params, Path(args.out))
    print(json.dumps({k: v for k, v in meta.items() if k != "params"}, indent=2))


def cmd_simulate(args) -> None:
    from generators.lammps import slide as lammps_slide
    meta = lammps_slide.simulate(args.sim, Path(args.packing), Path(args.out))
    print(json.dumps({k: v for k, v in meta.items() if k not in ("params", "kinetic_energy")}, indent=2))


def cmd_convert(args) -> None:
    from generators import convert, h5md
    path = convert.convert(args.scene, Path(args.raw), Path(args.out))
    traj = h5md.read(path)
    print(f"{path}: {traj.n_frames} frames x {traj.n_particles} particles "
          f"({int((~traj.kinematic).sum())} moving), dim {traj.dim}")


def cmd_dataset(args) -> None:
    from generators import h5md, plots
    from surrogate import dataset
    stats = dataset.build(Path(args.sweep), Path(args.sims), Path(args.out_dir), args.connectivity_radius)
    print(json.dumps(stats, indent=2))
    if args.plot:
        import pandas as pd
        splits = pd.read_csv(Path(args.out_dir) / "splits.csv")
        first = splits[splits["split"] == "train"].iloc[0]
        traj = h5md.read(first["path"])
        names = {int(k): v for k, v in dict(traj.parameters.get("species_names") or {}).items()}
        plots.first_last(args.plot, traj.position, traj.radius, traj.species, traj.time,
                         traj.box_lower, traj.box_upper, f"{args.scene}: {first['id']}", names)


def cmd_inspect(args) -> None:
    from generators import h5md
    for path in args.files:
        traj = h5md.read(path)
        print(f"{path}: valid H5MD, {traj.n_frames} frames, {traj.n_particles} particles "
              f"({int(traj.kinematic.sum())} kinematic), dim {traj.dim}, "
              f"t = {traj.time[0]:.4g}..{traj.time[-1]:.4g} s")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="graphdem",
        description="Graph-DEM pipeline: DEM sweeps (LAMMPS) to H5MD datasets. The Snakemake "
                    "workflow calls these subcommands; they can also be run by hand.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("config", help="print the resolved, validated configuration")
    p.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="override, e.g. --set scale=ci --set slide.young=5e9 (repeatable)")
    p.set_defaults(func=cmd_config)

    p = sub.add_parser("sweep", help="write the sweep table (one row per simulation)")
    p.add_argument("--scene", choices=SCENES, required=True)
    p.add_argument("--config-json", type=_json, required=True, help="the scene's resolved config section")
    p.add_argument("--out", type=Path, required=True, help="CSV to write")
    p.set_defaults(func=cmd_sweep)

    p = sub.add_parser("prepare", help="settle one packing under gravity (shared by many sims)")
    p.add_argument("--scene", choices=SCENES, required=True)
    p.add_argument("--params", type=_json, required=True, help="packing parameters (JSON)")
    p.add_argument("--out", type=Path, required=True, help="packing folder to write")
    p.set_defaults(func=cmd_prepare)

    p = sub.add_parser("simulate", help="run one simulation of the sweep with the DEM engine")
    p.add_argument("--scene", choices=SCENES, required=True)
    p.add_argument("--sim", type=_json, required=True, help="the sim's sweep row (JSON)")
    p.add_argument("--packing", type=Path, required=True, help="settled packing folder")
    p.add_argument("--out", type=Path, required=True, help="raw output folder to write")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("convert", help="convert a raw engine output folder to H5MD")
    p.add_argument("--scene", choices=SCENES, required=True)
    p.add_argument("--raw", type=Path, required=True)
    p.add_argument("--out", type=Path, required=True, help="H5MD file to write")
    p.set_defaults(func=cmd_convert)

    p = sub.add_parser("dataset", help="write splits.csv and stats.json (train split only)")
    p.add_argument("--scene", choices=SCENES, required=True)
    p.add_argument("--sweep", type=Path, required=True)
    p.add_argument("--sims", type=Path, required=True, help="folder of <id>.h5 files")
    p.add_argument("--out-dir", type=Path, required=True)
    p.add_argument("--connectivity-radius", type=float, required=True, help="graph radius R (m)")
    p.add_argument("--plot", type=Path, help="PNG of the first train sim's first and last frame")
    p.set_defaults(func=cmd_dataset)

    p = sub.add_parser("inspect", help="validate H5MD files and print a summary")
    p.add_argument("files", nargs="+", type=Path)
    p.set_defaults(func=cmd_inspect)
    return parser


def main(argv: list[str] | None = None) -> int:
    from generators import contact, h5md, stability
    from generators.lammps import io as lammps_io
    from generators.lammps import runner

    args = build_parser().parse_args(argv)
    try:
        args.func(args)
    except (gconfig.ConfigError, h5md.H5MDError, stability.BlowUp, contact.UnstableTimeStep,
            runner.LammpsError, lammps_io.LammpsOutputError, FileNotFoundError, ValueError) as exc:
        print(f"graphdem {args.command}: error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
