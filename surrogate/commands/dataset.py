"""`graphdem dataset` (the split table and the train split's statistics) and `graphdem contacts` (the next-frame
contacts a graph of radius R, capped or not, would miss): surrogate/dataset.py and surrogate/contacts.py."""

from __future__ import annotations

import json
from pathlib import Path

from generators import cli as gcli
from generators.cli_paths import input_path, output_file, output_folder, split_table
from surrogate.commands import options


def register(sub) -> None:
    p = gcli.add_command(sub, "dataset", run_dataset, help="write splits.csv and stats.json (train split only)")
    options.scene_or_benchmark(p, True, "the sims are of (the plot's title)")
    p.add_argument("--table", type=split_table, required=True, help="sweep.csv or a split table (id, split[, path])")
    p.add_argument("--sims", type=input_path, help="folder of <id>.h5 files, for a table without a path column")
    p.add_argument("--out-dir", type=output_folder, required=True)
    p.add_argument("--connectivity-radius", type=float, required=True, help="graph radius R (m)")
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
    files are --sims/<id>.h5) or a split table with a path column, such as the one import-solidgn writes."""
    import pandas as pd

    from surrogate import dataset
    table = pd.read_csv(args.table)
    if "path" not in table.columns:
        if args.sims is None:
            raise SystemExit(f"graphdem dataset: {args.table} has no path column; give --sims, the folder of <id>.h5")
        table = dataset.split_table(table, Path(args.sims))
    stats = dataset.build(table, Path(args.out_dir), args.connectivity_radius, args.max_neighbours)
    print(json.dumps(stats, indent=2))
    _report(stats)
    if args.plot:
        _plot_first_train_sim(args)


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


def _plot_first_train_sim(args) -> None:
    """--plot: the first train sim's first and last frame (3D: a vertical section through the middle)."""
    import pandas as pd

    from generators import h5md, plots
    splits = pd.read_csv(Path(args.out_dir) / "splits.csv")
    first = splits[splits["split"] == "train"].iloc[0]
    traj = h5md.read(first["path"])
    names = {int(k): v for k, v in dict(traj.parameters.get("species_names") or {}).items()}
    position, radius, lower, upper = traj.position, traj.radius, traj.box_lower, traj.box_upper
    title, ylabel = f"{args.name}: {first['id']}", "y (m)"
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
