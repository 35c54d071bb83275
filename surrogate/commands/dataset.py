"""`graphdem dataset` (the split table and the train split's statistics) and `graphdem contacts` (the next-frame
contacts a graph of radius R, capped or not, would miss): surrogate/dataset.py and surrogate/contacts.py."""

from __future__ import annotations

import json
import os
from pathlib import Path

from generators import cli as gcli
from generators.cli_paths import input_path, output_file, output_folder, split_table
from surrogate.commands import options


def register(sub) -> None:
    p = gcli.add_command(sub, "dataset", run_dataset, help="write splits.csv and stats.json (train split only)")
    options.scene_or_benchmark(p, True, "the sims are of (the plot's title)",
                               user_data="a folder of H5MD sims of your own (*.h5; docs/user-data.md): split here, by "
                                         "--fractions and --seed, instead of read from --table")
    p.add_argument("--table", type=split_table, help="sweep.csv or a split table (id, split[, path]); with --scene or "
                                                     "--benchmark")
    p.add_argument("--sims", type=input_path, help="folder of <id>.h5 files, for a table without a path column")
    p.add_argument("--out-dir", type=output_folder, required=True)
    p.add_argument("--connectivity-radius", type=float,
                   help="graph radius R (m); with --scene or --benchmark. With --user-data, default: the config's "
                        "user.connectivity_radius, where auto --connectivity-diameters mean diameters of the train "
                        "split's moving particles")
    user = p.add_argument_group("user data (--user-data; defaults: the config's user section, docs/user-data.md)")
    user.add_argument("--fractions", type=float, nargs=3, metavar=("TRAIN", "VALID", "TEST"),
                      help="the split's fractions (user.split)")
    user.add_argument("--seed", type=int, help="the split's shuffle (user.seed)")
    user.add_argument("--connectivity-diameters", type=float, metavar="D",
                      help="R = D mean diameters of the train split's moving particles, where no "
                           "--connectivity-radius is given (user.connectivity_diameters)")
    user.add_argument("--min-frames", type=int, metavar="N",
                      help="frames every sim must hold (user.model.history + bundle: a training sample)")
    p.add_argument("--max-neighbours", type=int,
                   help="a neighbour cap (the model's max_neighbours): stats.json reports the share of receivers "
                        "it truncates and of edges it drops on the train split; default: no cap")
    p.add_argument("--plot", type=output_file, help="PNG of the first train sim's first and last frame")

    p = gcli.add_command(sub, "contacts", run_contacts,
                         help="next-frame contacts a graph of radius R, capped or not, would miss")
    p.add_argument("--splits", type=split_table, required=True, help="a dataset's splits.csv (id, split, path)")
    p.add_argument("--split", default="train", help="the split to count (default: train)")
    p.add_argument("--radius", type=float, nargs="+", required=True, metavar="R", help="connectivity radii (m)")
    p.add_argument("--cap", type=int, nargs="*", metavar="N",
                   help="neighbour caps (senders per receiver, at most 64); no cap is always a row")
    p.add_argument("--sims", type=int, help="only the split's first N sims")
    p.add_argument("--out", type=output_file, help="also write the table as CSV")


def run_dataset(args) -> None:
    """Split table and normalisation statistics of the train split. --table is a scene's sweep.csv (id, split; the
    files are --sims/<id>.h5) or a split table with a path column, such as the one import-solidgn writes. With
    --user-data FOLDER instead (any folder of H5MD sims, docs/user-data.md): the folder's sims, sorted by name, split
    by --fractions with the seeded shuffle of a scene's sweep, every sim checked to hold --min-frames frames, and R,
    where not given, derived from the train split's radii; stats.json records the folder, and the evaluation of a
    model trained on it scores the generic metrics only (rollout MSE, plausibility, kinetic energy)."""
    import pandas as pd

    from surrogate import dataset
    if args.user_data is not None:
        stats = _user_dataset(args)
    else:
        if args.table is None or args.connectivity_radius is None:
            raise SystemExit("graphdem dataset: --table and --connectivity-radius are needed with --scene or "
                             "--benchmark")
        table = pd.read_csv(args.table)
        if "path" not in table.columns:
            if args.sims is None:
                raise SystemExit(f"graphdem dataset: {args.table} has no path column; give --sims, the folder of "
                                 "<id>.h5")
            table = dataset.split_table(table, Path(args.sims))
        stats = dataset.build(table, Path(args.out_dir), args.connectivity_radius, args.max_neighbours)
    print(json.dumps(stats, indent=2))
    _report(stats)
    if args.plot:
        _plot_first_train_sim(args, args.name or Path(os.path.abspath(args.user_data)).name)


def _user_dataset(args) -> dict:
    """The dataset of --user-data: each setting left out taken from the package config's ``user`` section."""
    from generators import config as gconfig
    from surrogate import dataset
    if args.table is not None or args.sims is not None:
        raise SystemExit("graphdem dataset: --user-data splits its folder itself; --table and --sims go with --scene "
                         "or --benchmark")
    user = gconfig.load()["user"]
    radius = args.connectivity_radius
    if radius is None and user["connectivity_radius"] != "auto":
        radius = float(user["connectivity_radius"])
    model = user["model"]
    min_frames = args.min_frames or model["history"] + model.get("bundle", 1)
    return dataset.build_user(
        Path(args.user_data), Path(args.out_dir), args.fractions or user["split"],
        user["seed"] if args.seed is None else args.seed, radius,
        args.connectivity_diameters or user["connectivity_diameters"], min_frames, args.max_neighbours)


def _report(stats: dict) -> None:
    """The neighbour counts and the contacts the radius misses, in words (and a warning where too many)."""
    from surrogate import dataset
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


def _plot_first_train_sim(args, name: str) -> None:
    """--plot: the first train sim's first and last frame (3D: a vertical section through the middle), titled by
    ``name``."""
    import pandas as pd

    from generators import h5md, plots
    splits = pd.read_csv(Path(args.out_dir) / "splits.csv")
    first = splits[splits["split"] == "train"].iloc[0]
    traj = h5md.read(first["path"])
    names = {int(k): v for k, v in dict(traj.parameters.get("species_names") or {}).items()}
    position, radius, lower, upper = traj.position, traj.radius, traj.box_lower, traj.box_upper
    title, ylabel = f"{name}: {first['id']}", "y (m)"
    if traj.dim == 3:                       # a vertical section through the middle, seen from the side
        mid = 0.5 * float(lower[1] + upper[1])
        position, radius = plots.plane_section(position, radius, mid, axis=1)
        lower, upper, ylabel = lower[[0, 2]], upper[[0, 2]], "z (m)"
        title += f", section y = {mid:.4g} m"
    plots.first_last(args.plot, position, radius, traj.species, traj.time, lower, upper, title, names,
                     ylabel=ylabel)


def run_contacts(args) -> None:
    """For each R and neighbour cap N: the share of next-frame contacts (a moving receiver, a sender touching it one
    frame later) whose sender is R or farther away, or not among the receiver's N nearest, in the frame the graph is
    built on; and the senders per receiver the graph keeps. The contact-miss rate that chooses R and max_neighbours
    (docs/surrogate.md, Neighbour cap)."""
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
        options.write_rows(rows, args.out)
