"""The options several `graphdem` subcommands share, and what their commands make of them: the checkpoint and
its sims, the device, the runtime switches, logging, writing a table (the evaluation's own, the scene metrics'
and the bootstrap intervals, are in evaluation/commands/metric_options.py)."""

from __future__ import annotations

import argparse
from pathlib import Path

from generators import cli as gcli
from generators.cli_paths import input_path

json_arg = gcli.json_arg


def log_to_stderr(quiet: bool = False) -> None:
    """INFO lines on stderr; only warnings where ``quiet`` (the processes of a multi-process training but rank 0)."""
    import logging
    logging.basicConfig(level=logging.WARNING if quiet else logging.INFO,
                        format="%(asctime)s %(name)s %(levelname)s: %(message)s")


def checkpoint_and_data(p: argparse.ArgumentParser, data_required: bool = True, ensemble: bool = False) -> None:
    if ensemble:
        p.add_argument("--checkpoint", type=input_path, nargs="+", required=True,
                       help="a best.pt or last.pt written by train; several: an ensemble, every step the mean of "
                            "their accelerations is integrated (the models must share history, R, the neighbour "
                            "cap, the frame interval, box and types; docs/surrogate.md)")
    else:
        p.add_argument("--checkpoint", type=input_path, required=True, help="a best.pt or last.pt written by train")
    p.add_argument("--data", type=input_path, nargs="+", required=data_required, help="H5MD files or folders of them")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    p.add_argument("--allow-other-scene", action="store_true",
                   help="score sims of another scene (or other kinematic species) than the checkpoint was trained on")
    p.add_argument("--runtime-json", type=json_arg,
                   help="the scene's runtime switches (JSON: split_edge_mlp, skip_kinematic_pairs, prune_isolated, "
                        "precision, sleep_speed, keep_in_domain, compile, optionally contact_correction; "
                        "docs/performance.md); default: compute as in training")
    device_option(p, "auto")


def scene_or_benchmark(p: argparse.ArgumentParser, required: bool, what: str, user_data: str | None = None) -> None:
    """``--scene`` (a registered scene) or ``--benchmark`` (a public benchmark), never both, into ``args.name``:
    ``what`` says what the subcommand takes of it. With ``user_data`` (its help), the third choice ``--user-data
    FOLDER`` (a folder of H5MD sims, docs/user-data.md) into ``args.user_data``."""
    from generators import scenes
    group = p.add_mutually_exclusive_group(required=required)
    group.add_argument("--scene", dest="name", choices=scenes.names(), help=f"the scene {what}")
    group.add_argument("--benchmark", dest="name", choices=sorted(gcli.gconfig.BENCHMARKS),
                       help=f"the public benchmark {what}")
    if user_data:
        group.add_argument("--user-data", type=input_path, metavar="FOLDER", help=user_data)


def device_option(p: argparse.ArgumentParser, default: str | None) -> None:
    from surrogate import devices
    p.add_argument("--device", type=device_arg, default=default,
                   help=f"where the model computes: {devices.CHOICES} (auto: the first CUDA GPU torch sees, else the "
                        "CPU; under torchrun each process takes its LOCAL_RANK's GPU; docs/scaling.md)"
                        + ("" if default else "; default: the config's device key with --scene or --benchmark, "
                                              "else auto"))


def device_arg(value: str) -> str:
    """An argparse type: a device setting (surrogate/devices.py)."""
    from surrogate import devices
    if not devices.SPEC.match(value):
        raise argparse.ArgumentTypeError(f"{value!r}: allowed are {devices.CHOICES}")
    return value


def runtime_config(args, required_by: str | None = None):
    """The Runtime of --runtime-json; None without it, unless the command ``required_by`` needs it."""
    from surrogate import runtime
    if args.runtime_json is None:
        if required_by:
            raise SystemExit(f"graphdem {required_by}: --runtime-json is required (the scene's runtime config)")
        return None
    return runtime.Runtime.from_config(args.runtime_json)


def apply_runtime(args, simulator):
    """The simulator prepared for the --runtime-json switches, and the Runtime (None without)."""
    from surrogate import runtime
    rt = runtime_config(args)
    return (simulator, None) if rt is None else (runtime.apply(simulator, rt), rt)


def write_rows(rows: list[dict], out: Path) -> None:
    """``rows`` as a CSV table at ``out``, written atomically."""
    import pandas as pd

    from generators.atomic import atomic_path
    with atomic_path(out) as tmp:
        pd.DataFrame(rows).to_csv(tmp, index=False)


def write_table(table, out: Path, **to_csv) -> None:
    """A DataFrame as CSV at ``out``, written atomically (``to_csv``: pandas' options, index=False by default)."""
    from generators.atomic import atomic_path
    with atomic_path(out) as tmp:
        table.to_csv(tmp, **{"index": False, **to_csv})
