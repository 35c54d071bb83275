"""`graphdem import FORMAT SOURCE OUT_DIR`: the trajectories of other tools as H5MD sims (docs/import.md). Its
options and its run function; generators/cli.py registers it beside import-solidgn."""

from __future__ import annotations

import argparse
import re
from collections import Counter
from pathlib import Path

from generators.cli_paths import input_path, replaced_folder
from generators.importers.metadata import PER_TYPE, ImportRefused, given, option_value
from generators.importers.sims import MARKER

FORMATS = ("gns", "lagrangebench", "lammps-dump")
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")

HELP = "convert GNS .npz, LagrangeBench HDF5 or LAMMPS dump trajectories to H5MD sims"
EPILOG = """\
formats:
  gns            a GNS dataset folder (train.npz, valid.npz, test.npz; metadata.json with bounds, dt,
                 dim, default_connectivity_radius) or one .npz; each entry (positions [T, N, D],
                 particle_type [N]) as GNS and learning_to_simulate store them. Object arrays are read
                 with an unpickler that admits numpy arrays and nothing else.
  lagrangebench  a LagrangeBench dataset folder (train.h5, valid.h5, test.h5 of groups 00000, 00001,
                 ... holding position and particle_type; metadata.json with bounds, dt, write_every,
                 periodic_boundary_conditions) or one .h5
  lammps-dump    a LAMMPS text dump (dump custom: id type x y z [radius mass ...]) or a folder of
                 them, one trajectory each; 2D where z is constant (or --dim 2)

items the source lacks come from the options or from --meta FILE (YAML or JSON, keys radius,
density or mass, kinematic_types, box, dt or frame_interval, dim; options win over it). Where the
source holds an item, a given one must agree with it. A missing radius, mass (or density), box or
time step refuses the import, naming the option and the key that give it. Kinematic types default
to the format's convention: 3 (GNS), 1 and 2 (LagrangeBench), none (LAMMPS).

writes OUT_DIR/NAME_0000.h5, ... (one per trajectory), splits.csv (id, split, path, source; for
graphdem dataset --table) where the source has train/valid/test splits, and import.json (each
file's SHA-256 and the items used); OUT_DIR is replaced whole, atomically. See docs/import.md.
"""


def add_options(p: argparse.ArgumentParser) -> None:
    """The arguments of `graphdem import`; its epilog keeps its layout."""
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.add_argument("format", choices=FORMATS, metavar="FORMAT", help=f"the source's format: {', '.join(FORMATS)}")
    p.add_argument("source", type=input_path, metavar="SOURCE", help="the dataset folder or file to import")
    p.add_argument("out_dir", type=replaced_folder(MARKER), metavar="OUT_DIR",
                   help="the folder to write (replaced whole; an existing one must be an earlier import's)")
    p.add_argument("--meta", type=input_path, metavar="FILE",
                   help="YAML or JSON file of the items the source lacks (keys: radius, density, mass, "
                        "kinematic_types, box, dt, frame_interval, dim); options win over it")
    for key, unit in (("radius", "m"), ("density", "kg/m^3"), ("mass", "kg")):
        p.add_argument(f"--{key}", action="append", metavar="V|TYPE=V",
                       help=f"particle {key} ({unit}): one number for all, or TYPE=V per particle type (repeated)")
    p.add_argument("--kinematic-types", type=int, nargs="*", metavar="TYPE",
                   help="particle types whose positions are prescribed (none given: no kinematic particles); "
                        "default: the format's convention")
    p.add_argument("--box", type=float, nargs="+", metavar="LO HI",
                   help="the domain box, LO HI per axis (4 or 6 numbers, m)")
    p.add_argument("--dt", type=float, help="seconds per step: the LAMMPS timestep, a GNS frame, a LagrangeBench "
                                            "solver step")
    p.add_argument("--frame-interval", type=float, help="seconds between recorded frames (evenly spaced)")
    p.add_argument("--dim", type=int, choices=(2, 3), help="the dimension (a LAMMPS dump with constant z is 2D)")
    p.add_argument("--name", help="the sims' file prefix and dataset name (default: SOURCE's name)")
    p.add_argument("--limit", type=int, metavar="N", help="import only the first N trajectories of each file")


def _options(args: argparse.Namespace) -> dict:
    """The items the options give (None where not given)."""
    options = {key: option_value(key, getattr(args, key)) if getattr(args, key) else None for key in PER_TYPE}
    box = args.box
    if box is not None:
        if len(box) not in (4, 6):
            raise ImportRefused(f"--box takes LO HI per axis (4 numbers in 2D, 6 in 3D), got {len(box)}")
        box = [box[i:i + 2] for i in range(0, len(box), 2)]
    return {**options, "kinematic_types": args.kinematic_types, "box": box, "dt": args.dt,
            "frame_interval": args.frame_interval, "dim": args.dim}


def _name(args: argparse.Namespace, source: Path) -> str:
    from generators import scenes
    name = args.name or (source.resolve().name if source.is_dir() else source.name.split(".")[0])
    if not NAME.fullmatch(name):
        raise ImportRefused(f"--name {name!r}: a name of letters, digits, '.', '_' and '-' (it names the files)")
    if name in scenes.names():
        raise ImportRefused(f"--name {name!r} is a registered scene's; imported sims need a name of their own")
    return name


def run(args: argparse.Namespace) -> None:
    """Turn the trajectories another tool wrote (FORMAT: gns, lagrangebench or lammps-dump) in SOURCE into H5MD
    sims in OUT_DIR, one NAME_<i>.h5 per trajectory, each carrying its provenance (source format, file and its
    SHA-256, entry, the importer's options) in its parameters. Per-particle radius, mass, the box, kinematic types
    and the time step come from the source where it holds them, else from the options or --meta."""
    from generators.importers import gns, lagrangebench, lammps_dump, sims
    source = Path(args.source)
    if not source.exists():
        raise ImportRefused(f"{source}: no such file or folder")
    if args.limit is not None and args.limit < 1:
        raise ImportRefused(f"--limit {args.limit}: import at least 1 trajectory of each file")
    items = given(_options(args), args.meta)
    record = {"format": args.format, "source": str(source), "name": _name(args, source), "limit": args.limit,
              "meta": None if args.meta is None else str(args.meta), "items": items.record()}
    reader = {"gns": gns.sources, "lagrangebench": lagrangebench.sources, "lammps-dump": lammps_dump.sources}
    rows = sims.write(Path(args.out_dir), reader[args.format](source, items, args.limit), items, record)
    splits = Counter(row["split"] for row in rows if row["split"] is not None)
    print(f"{args.out_dir}: {len(rows)} sims from {source} ({args.format})"
          + (f", splits {dict(splits)} in {Path(args.out_dir) / 'splits.csv'}" if splits else ""))
