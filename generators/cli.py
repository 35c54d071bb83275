"""The generators' stages on the `graphdem` command line: config, sweep, prepare, simulate, convert,
inspect, export, import-solidgn, import, stability-dem, restitution, physics, crosscheck and transfer, each added
by its registrar (REGISTRARS; graphdem/cli.py adds the surrogate's and runs them all).

Every subcommand writes its outputs atomically and exits non-zero with a one-line reason
(naming the file, sim, frame or config key) when something is wrong.
"""

from __future__ import annotations

import argparse
import inspect
import json
import pickle
from collections.abc import Callable
from pathlib import Path

from generators import config as gconfig
from generators import engines, scenes
from generators.cli_paths import input_path, output_file, output_series, replaced_folder, run_folder
from generators.importers import cli as importers_cli


def add_command(sub, name: str, run: Callable[[argparse.Namespace], None], help: str,
                epilog: str | None = None) -> argparse.ArgumentParser:
    """Add the subcommand ``name`` to the `graphdem` subparsers ``sub``: `graphdem --help` lists it with ``help``, its
    own ``--help`` describes it with ``run``'s docstring (and ends with ``epilog``), and it runs ``run(args)``."""
    parser = sub.add_parser(name, help=help, description=inspect.getdoc(run), epilog=epilog)
    parser.set_defaults(func=run)
    return parser


def json_arg(text: str) -> dict:
    """An argparse type: a JSON object or list."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not valid JSON: {exc}") from exc


def config_options(p: argparse.ArgumentParser) -> None:
    """``--config FILE`` and ``--set KEY=VALUE``: the workflow's config keys, on top of the package defaults."""
    p.add_argument("--config", dest="config_file", type=input_path, metavar="FILE", action="append",
                   help="YAML file of config keys, as Snakemake's --configfile takes them (repeatable; later "
                        "files win)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="override one key by its dotted path, e.g. --set scale=ci --set slide.young=5e9 "
                        "--set slide.train.lr=1e-3 (repeatable; wins over --config)")


def resolved_config(args) -> dict:
    """The package defaults, the ``--config`` files and the ``--set`` keys, resolved and validated."""
    import yaml
    overrides: dict = {}
    for path in args.config_file or []:
        try:
            data = yaml.safe_load(Path(path).read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise gconfig.ConfigError(f"--config {path}: cannot be read as YAML: {exc}") from exc
        if not isinstance(data, dict):
            raise gconfig.ConfigError(f"--config {path}: must hold a mapping of config keys, got "
                                      f"{type(data).__name__}")
        overrides = gconfig.deep_update(overrides, data)
    for item in args.set or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise gconfig.ConfigError(f"--set {item!r}: expected KEY=VALUE, e.g. --set slide.young=5e9")
        node: dict = {}
        leaf_parent = node
        *parents, leaf = key.split(".")
        for part in parents:
            leaf_parent = leaf_parent.setdefault(part, {})
        leaf_parent[leaf] = yaml.safe_load(value)
        overrides = gconfig.deep_update(overrides, node)
    return gconfig.load(overrides)


def cmd_config(args) -> None:
    """The package defaults with the chosen scale preset, --config files and --set keys on top, validated against the
    schema: what the workflow runs with."""
    import yaml
    print(yaml.safe_dump(resolved_config(args), sort_keys=False))


def cmd_sweep(args) -> None:
    from generators import sweep
    from generators.atomic import atomic_path
    table = sweep.build(args.scene, args.config_json)
    with atomic_path(args.out) as tmp:
        table.to_csv(tmp, index=False)
    print(f"{args.out}: {len(table)} simulations, splits {table['split'].value_counts().to_dict()}")


def cmd_prepare(args) -> None:
    from generators import engine
    rec = engine.prepare(scenes.get(args.scene), args.engine, args.params, Path(args.out), ranks=args.ranks)
    print(f"{args.out}: settled in {rec.run.engine} ({rec.settle_steps} steps, {rec.run.wall_time:.1f} s"
          f"{_on_ranks(rec.run.ranks)}), "
          f"{rec.n_moving} moving and {rec.n_kinematic} kinematic particles")


def cmd_simulate(args) -> None:
    from generators import engine
    rec = engine.simulate(scenes.get(args.scene), args.sim, Path(args.packing), Path(args.out), ranks=args.ranks)
    print(f"{args.out}: {rec.run.engine} {rec.run.version}, dt = {rec.dt:.4g} s ({rec.dt / rec.dt_limit:.3g} x the "
          f"stable limit), {rec.steps_per_frame} steps per frame, {rec.run.wall_time:.1f} s{_on_ranks(rec.run.ranks)}")


def _on_ranks(ranks: int) -> str:
    return f" on {ranks} MPI ranks" if ranks > 1 else ""


def cmd_convert(args) -> None:
    from generators import convert, h5md
    path = convert.convert(Path(args.raw), Path(args.out))
    traj = h5md.read(path)
    print(f"{path}: {traj.n_frames} frames x {traj.n_particles} particles "
          f"({int((~traj.kinematic).sum())} moving), dim {traj.dim}")


def cmd_stability_dem(args) -> None:
    """Stability test of the DEM: the sim of --sim run with dt = f x the stable limit for every f of --factors, through
    the same blow-up detectors as the dataset (non-finite values, escapes, overlaps, energy growth). Writes one row
    per f: stable, or the frame and cause of the blow-up; raw output is discarded."""
    import tempfile

    from generators import stability
    from generators.atomic import atomic_path
    with tempfile.TemporaryDirectory(prefix="graphdem-stability-") as scratch:
        table = stability.dem_time_steps(args.scene, args.sim, Path(args.packing), args.factors, Path(scratch))
    with atomic_path(args.out) as tmp:
        table.to_csv(tmp, index=False)
    for row in table.to_dict("records"):
        outcome = "stable" if row["stable"] else f"BLOWS UP at frame {row['frame']}: {row['cause']}"
        print(f"{row['sim']}, {row['setting']}: {outcome}")


def cmd_restitution(args) -> None:
    """Collide two spheres of the scene's material head-on in each engine, at each --dt-safety x the scene's stable
    limit, for its smallest and its nominal sphere, at --phases approach speeds (each starts the contact at another
    point of a time step); report the largest and median error of the restitution against the configured one. The
    design asks for at most 2 %: the cheapest step a scene can take is the largest that passes in every row
    (docs/performance.md, "The DEM's time step")."""
    import tempfile

    from generators import collision
    from generators.atomic import atomic_path
    cfg = resolved_config(args)
    scene = scenes.get(args.scene)
    setup = scene.settle_setup(scene.packings(cfg[args.scene])[0])
    dt_safeties = args.dt_safety or [setup.dt / setup.dt_limit]
    with tempfile.TemporaryDirectory(prefix="graphdem-restitution-") as scratch:
        table = collision.time_step_table(setup, args.engines, dt_safeties, args.phases, args.tolerance,
                                          Path(scratch))
    table.insert(0, "scene", args.scene)
    with atomic_path(args.out) as tmp:
        table.to_csv(tmp, index=False)
    print(f"{args.scene}: restitution {setup.contact.restitution} measured over {args.phases} impact phases; "
          f"tolerance {args.tolerance:.1%}")
    for row in table.to_dict("records"):
        print(f"dt_safety {row['dt_safety']:g}, {row['engine']}, {row['pair']} pair (r {row['radius']:.4g}): "
              f"max error {row['max_error']:.2%}, median {row['median_error']:.2%}: "
              f"{'passes' if row['passes'] else 'FAILS'}")
    passing = [f for f in dt_safeties if table.loc[table["dt_safety"] == f, "passes"].all()]
    print(f"largest step of those tried that passes everywhere: "
          f"{'dt_safety ' + format(max(passing), 'g') if passing else 'none'}")


def cmd_import_solidgn(args) -> None:
    """Convert SRC (metadata.json and train/, valid/, test/ of Solid-GN .pkl trajectories) into
    DEST/sims/<split>_<n>.h5 and DEST/splits.csv. Pickles are read with an unpickler that admits numpy arrays and
    nothing else."""
    from generators.solidgn import convert
    limits = {}
    for item in args.limit or []:
        split, _, count = item.partition("=")
        if not count.isdigit() or int(count) < 1:
            raise SystemExit(f"graphdem import-solidgn: --limit {item!r}: expected SPLIT=N with N >= 1")
        limits[split] = int(count)
    table = convert.import_dataset(args.src, args.dest, progress=not args.no_progress, limits=limits)
    print(f"{args.dest}: {len(table)} sims, splits {table['split'].value_counts().to_dict()}")


def cmd_inspect(args) -> None:
    from generators import h5md
    for path in args.files:
        traj = h5md.read(path)
        print(f"{path}: valid H5MD, {traj.n_frames} frames, {traj.n_particles} particles "
              f"({int(traj.kinematic.sum())} kinematic), dim {traj.dim}, "
              f"t = {traj.time[0]:.4g}..{traj.time[-1]:.4g} s")


def positive_int(text: str) -> int:
    """An argparse type: a whole number >= 1."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return value


def cmd_export(args) -> None:
    """Write TRAJECTORY (an H5MD sim or Graph-DEM rollout) as the ParaView time series --out NAME.pvd: one .vtu per
    exported frame in the folder NAME/ beside it, each frame's time in the .pvd. Point data: id, type (species),
    radius (m), mass (kg), kinematic (0/1), velocity (m/s; backward difference of the recorded frames, the first
    frame takes the forward one), every per-particle property by name, and with --truth the rollout error: error (m,
    distance to the truth's position) and error_radii (in the particle's radii). 2D gets z = 0. Written atomically:
    the .pvd appears last. Open NAME.pvd in ParaView (docs/export.md)."""
    from generators import export
    series = export.export_file(args.trajectory, args.out, args.truth, args.every)
    print(f"{series.pvd}: {len(series.frames)} frames (every {args.every}), t = {series.times[0]:.4g}.."
          f"{series.times[-1]:.4g} s, in {series.frames_dir}/ ({series.seconds:.2f} s)"
          f"{f', error against {args.truth}' if args.truth else ''}")


def cmd_crosscheck(args) -> None:
    """One row per scene metric and pair of engines (its value at each sim's last frame): both engines' mean and
    standard deviation over the sims, their relative difference and pass/fail against the larger of --tolerance and
    the combined standard error (docs/crosscheck.md). With --combine, stack finished tables instead."""
    import pandas as pd

    from generators import crosscheck
    from generators.atomic import atomic_path
    runs = {name: getattr(args, name) for name in engines.NAMES if getattr(args, name, None)}
    if args.combine:
        table = pd.concat([pd.read_csv(p) for p in args.combine], ignore_index=True)
    elif args.scene is None or len(runs) < 2:
        raise SystemExit(f"graphdem crosscheck: give --scene, {_engine_flags()}, or --combine TABLES")
    else:
        table = crosscheck.compare(args.scene, runs, args.tolerance, args.body_displacement, args.chaos)
    with atomic_path(args.out) as tmp:
        table.to_csv(tmp, index=False)
    print(table.to_string(index=False))


def cmd_transfer(args) -> None:
    """Stack two `graphdem evaluate` tables of one checkpoint: on the test sims of the engine it was trained on
    (--same) and on the same rows run in the other engine (--other)."""
    import pandas as pd

    from generators import crosscheck
    from generators.atomic import atomic_path
    table = crosscheck.transfer(pd.read_csv(args.same), pd.read_csv(args.other), args.trained_on, args.other_engine)
    with atomic_path(args.out) as tmp:
        table.to_csv(tmp, index=False)
    print(table.to_string(index=False))


def cmd_physics(args) -> None:
    """The scene's own physics check on its sims, e.g. the column collapse's runout against the aspect ratio beside the
    published laws (docs/collapse-scene.md)."""
    from generators import h5md
    scene = scenes.get(args.scene)
    if not scene.has_physics:
        have = [n for n, s in scenes.registry().items() if s.has_physics]
        raise ValueError(f"the {scene.name} scene has no physics check; scenes with one: {', '.join(have) or 'none'}")
    trajectories = [h5md.read(p) for p in args.data]
    cfg = args.config_json if args.config_json is not None else gconfig.defaults()[scene.name]
    table = scene.physics(trajectories, Path(args.out), Path(args.plot), cfg)
    print(table.to_string(index=False))


def _ranks_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--ranks", type=positive_int, default=1, metavar="N",
                   help="MPI ranks LAMMPS runs on (mpirun -np N on this host; default 1: no mpirun); YADE runs "
                        "take 1 only")


def _add_config(sub) -> None:
    p = add_command(sub, "config", cmd_config, help="print the resolved, validated configuration")
    config_options(p)


def _add_sweep(sub) -> None:
    p = add_command(sub, "sweep", cmd_sweep, help="write the sweep table (one row per simulation)")
    p.add_argument("--scene", choices=scenes.names(), required=True)
    p.add_argument("--config-json", type=json_arg, required=True, help="the scene's resolved config section")
    p.add_argument("--out", type=output_file, required=True, help="CSV to write")


def _add_prepare(sub) -> None:
    p = add_command(sub, "prepare", cmd_prepare, help="settle one packing under gravity (shared by many sims)")
    p.add_argument("--scene", choices=scenes.names(), required=True)
    p.add_argument("--engine", choices=engines.names(), required=True, help="the engine that settles it")
    p.add_argument("--params", type=json_arg, required=True, help="packing parameters (JSON)")
    p.add_argument("--out", type=run_folder, required=True, help="packing folder to write")
    _ranks_option(p)


def _add_simulate(sub) -> None:
    p = add_command(sub, "simulate", cmd_simulate, help="run one simulation of the sweep with the DEM engine")
    p.add_argument("--scene", choices=scenes.names(), required=True)
    p.add_argument("--sim", type=json_arg, required=True, help="the sim's sweep row (JSON)")
    p.add_argument("--packing", type=input_path, required=True, help="settled packing folder")
    p.add_argument("--out", type=run_folder, required=True, help="raw output folder to write")
    _ranks_option(p)


def _add_convert(sub) -> None:
    p = add_command(sub, "convert", cmd_convert, help="convert a raw engine output folder to H5MD")
    p.add_argument("--raw", type=input_path, required=True,
                   help="a simulate stage's raw folder (its run.json names the scene and the engine)")
    p.add_argument("--out", type=output_file, required=True, help="H5MD file to write")


def _add_stability_dem(sub) -> None:
    p = add_command(sub, "stability-dem", cmd_stability_dem,
                    help="run one sim at multiples of the stable DEM time step; report blow-ups")
    p.add_argument("--scene", choices=scenes.names(), required=True)
    p.add_argument("--sim", type=json_arg, required=True, help="one row of the sweep table (JSON)")
    p.add_argument("--packing", type=input_path, required=True, help="the sim's settled packing (prepare stage)")
    p.add_argument("--factors", type=float, nargs="+", required=True, help="time steps in units of the stable limit")
    p.add_argument("--out", type=output_file, required=True, help="CSV report")


def _add_restitution(sub) -> None:
    p = add_command(sub, "restitution", cmd_restitution,
                    help="measure a scene's two-sphere restitution at chosen DEM time steps")
    p.add_argument("--scene", choices=scenes.names(), required=True)
    p.add_argument("--dt-safety", type=float, nargs="+", metavar="F",
                   help="time steps in units of the stable limit (default: the scene's configured one)")
    p.add_argument("--engines", nargs="+", choices=engines.names(), default=engines.names(),
                   help="the engines to measure, in this order (default: every registered engine)")
    p.add_argument("--phases", type=positive_int, default=13, metavar="N", help="impact phases per step (default 13)")
    p.add_argument("--tolerance", type=float, default=0.02,
                   help="largest relative error that passes (default 0.02, the design's 2 %%)")
    p.add_argument("--out", type=output_file, required=True, help="CSV to write")
    config_options(p)


def _add_physics(sub) -> None:
    p = add_command(sub, "physics", cmd_physics,
                    help="check a scene's DEM data against published physics (table and plot)")
    p.add_argument("--scene", choices=scenes.names(), required=True)
    p.add_argument("--data", type=input_path, nargs="+", required=True, help="the scene's H5MD sims")
    p.add_argument("--out", type=output_file, required=True, help="CSV to write")
    p.add_argument("--plot", type=output_file, required=True, help="PNG to write")
    p.add_argument("--config-json", type=json_arg, default=None,
                   help="the scene's resolved config section (the workflow passes it); absent: the scene's defaults")


def _engine_flags() -> str:
    """The cross-check's options of the registered engines, in words: ``--a FILES and --b FILES``."""
    return " and ".join(f"--{name} FILES" for name in engines.NAMES)


def _add_crosscheck(sub) -> None:
    p = add_command(sub, "crosscheck", cmd_crosscheck,
                    help="compare a scene's metrics over the same sims run in each engine")
    p.add_argument("--scene", choices=scenes.names(),
                   help=f"the scene (with {' and '.join('--' + e for e in engines.NAMES)})")
    for name in engines.NAMES:
        p.add_argument(f"--{name}", type=input_path, nargs="+", help=f"the sims run in {name.upper()} (H5MD)")
    p.add_argument("--chaos", type=input_path, nargs="+",
                   help="the same sims rerun by one of the engines from perturbed packings (the DEM's own chaos)")
    p.add_argument("--tolerance", type=float, default=gconfig.defaults()["crosscheck"]["tolerance"],
                   help="relative tolerance on each metric's mean (default: the config's crosscheck.tolerance)")
    p.add_argument("--body-displacement", type=float, help="slide body threshold (m); default one mean diameter")
    p.add_argument("--combine", type=input_path, nargs="+", help="cross-check tables to stack (all scenes)")
    p.add_argument("--out", type=output_file, required=True, help="CSV to write")


def _add_transfer(sub) -> None:
    p = add_command(sub, "transfer", cmd_transfer,
                    help="a model's rollout MSE on its own engine's test sims beside the other's")
    p.add_argument("--same", type=input_path, required=True, help="metrics.csv on the training engine's test sims")
    p.add_argument("--other", type=input_path, required=True, help="metrics.csv on the other engine's test sims")
    p.add_argument("--trained-on", choices=engines.names(), required=True)
    p.add_argument("--other-engine", choices=engines.names(), required=True)
    p.add_argument("--out", type=output_file, required=True, help="CSV to write")


def _add_import_solidgn(sub) -> None:
    p = add_command(sub, "import-solidgn", cmd_import_solidgn,
                    help="convert a Solid-GN dataset folder (pickles) to H5MD")
    p.add_argument("src", type=input_path, help="the Solid-GN dataset folder")
    p.add_argument("dest", type=replaced_folder("splits.csv"), help="the folder to write (replaced whole)")
    p.add_argument("--limit", action="append", metavar="SPLIT=N",
                   help="import only the first N trajectories of SPLIT (train, valid or test; repeatable)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")


def _add_import(sub) -> None:
    p = add_command(sub, "import", importers_cli.run, help=importers_cli.HELP, epilog=importers_cli.EPILOG)
    importers_cli.add_options(p)


def _add_export(sub) -> None:
    p = add_command(sub, "export", cmd_export,
                    help="write an H5MD sim or rollout as a ParaView time series (.pvd of .vtu)")
    p.add_argument("trajectory", type=input_path, metavar="TRAJECTORY", help="H5MD file to export (a sim or a rollout)")
    p.add_argument("--out", type=output_series, required=True, metavar="NAME.pvd",
                   help="the .pvd to write; its frames go to the folder of the same name without .pvd")
    p.add_argument("--truth", type=input_path, metavar="DEM.h5",
                   help="the DEM sim a rollout was made from (same particles and frame times): adds the error")
    p.add_argument("--every", type=positive_int, default=1, metavar="K",
                   help="export every K-th recorded frame from the first (default 1: all)")


def _add_inspect(sub) -> None:
    p = add_command(sub, "inspect", cmd_inspect, help="validate H5MD files and print a summary")
    p.add_argument("files", nargs="+", type=input_path)


#: the generators' registrars, in the order `graphdem --help` lists their subcommands (graphdem/cli.py adds the
#: surrogate's after them); each adds one subcommand to the `graphdem` subparsers ``sub``, its scene and engine
#: choices from their registries
REGISTRARS = (_add_config, _add_sweep, _add_prepare, _add_simulate, _add_convert, _add_stability_dem,
              _add_restitution, _add_physics, _add_crosscheck, _add_transfer, _add_import_solidgn, _add_import,
              _add_export, _add_inspect)


def add_commands(sub) -> None:
    """Add the generators' subcommands to the `graphdem` subparsers ``sub``."""
    for register in REGISTRARS:
        register(sub)


def errors() -> tuple[type[Exception], ...]:
    """The generators' errors that `graphdem` reports as one line (exit status 1), every registered engine
    driver's own (its ``ERRORS``) among them."""
    from generators import blowup, contact, dem, export, h5md, record
    return (gconfig.ConfigError, h5md.H5MDError, export.ExportError, blowup.BlowUp, contact.UnstableTimeStep,
            dem.UnsupportedSetup, record.RecordError, *engines.errors(), pickle.UnpicklingError, FileNotFoundError,
            ValueError)
