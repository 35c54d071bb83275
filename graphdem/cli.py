"""The `graphdem` command: the pipeline's stages as subcommands; each Snakemake rule calls one.

Each stage registers its own subcommands (``register(sub)``, next to the code that runs them): the generators'
in generators/cli.py (config, sweep, prepare, simulate, convert, stability-dem, restitution, physics,
crosscheck, transfer, import-solidgn, export, inspect), the surrogate's in surrogate/commands/ (dataset,
contacts, train, rollout), the evaluation's in evaluation/commands/ (evaluate, combine, seeds, card,
property-sensitivity, shear-stress-readout, shear-stress-check, stability-surrogate, the performance stage's,
publish) and evaluation/doc_tables/ (tables: the docs' results tables).
Every subcommand writes its outputs atomically and exits non-zero with a one-line reason (naming the file, sim,
frame or config key) when something is wrong. Before it runs, the paths it writes are checked against the paths it
reads, as every path option declares them where it is added (generators/cli_paths.py).
"""

from __future__ import annotations

import argparse
import signal
import sys

from evaluation import doc_tables
from evaluation.commands import (
    card,
    evaluate,
    performance,
    property_sensitivity,
    publish,
    seeds,
    shear_stress,
    stability,
)
from generators import cli as gcli
from generators import cli_paths, scenes
from surrogate.commands import dataset, rollout, train

#: who adds which subcommands, in the order `graphdem --help` lists them
REGISTRARS = (
    *gcli.REGISTRARS,                   # config ... inspect: the generators' stages
    dataset.register,                   # dataset, contacts
    train.register,                     # train
    rollout.register,                   # rollout
    evaluate.register,                  # evaluate, combine
    seeds.register,                     # seeds
    card.register,                      # card
    property_sensitivity.register,      # property-sensitivity
    shear_stress.register,              # shear-stress-readout, shear-stress-check
    stability.register,                 # stability-surrogate
    performance.register,               # performance-dem, performance-surrogate, performance-report
    publish.register,                   # publish
    doc_tables.add_command,             # tables
)


class Parser(argparse.ArgumentParser):
    """argparse's parser, whose refusal of a value outside an option's choices adds the closest choice ("did you
    mean"); the subcommands' parsers are of this class too."""

    def _check_value(self, action, value):
        if action.choices is not None and value not in action.choices:
            from generators.errors import did_you_mean
            choices = ", ".join(map(repr, action.choices))
            hint = did_you_mean(value, list(action.choices)) if isinstance(value, str) else ""
            raise argparse.ArgumentError(action, f"invalid choice: {value!r}{hint} (choose from {choices})")
        return super()._check_value(action, value)


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="graphdem",
        description="Graph-DEM pipeline: DEM sweeps (LAMMPS, YADE) to H5MD datasets, then training, rollout and "
                    "evaluation of the Graph-DEM surrogate. The Snakemake workflow calls these subcommands; they "
                    f"can also be run by hand. Scenes: {', '.join(scenes.names())}.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for register in REGISTRARS:
        register(sub)
    return parser


def subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The subcommands' parsers of the `graphdem` parser ``parser``, by name."""
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


def errors() -> tuple[type[Exception], ...]:
    """The errors `graphdem` reports as one line on stderr (exit status 1): the generators' and the surrogate's."""
    from surrogate.errors import CheckpointError, TrainingDiverged
    return (*gcli.errors(), CheckpointError, TrainingDiverged)


def main(argv: list[str] | None = None) -> int:
    """Run one subcommand. A file-size limit (``ulimit -f``) does not kill the process (SIGXFSZ is ignored): the
    write fails with EFBIG, and that, like every OSError (a full disk, a folder not replaced by a file: the
    outputs' generators.atomic.OutputError, naming the file), is one line on stderr and exit status 1."""
    if hasattr(signal, "SIGXFSZ"):
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "complete", None) is not None:      # a subcommand's paths that default to the workflow's
        args.complete(args)
    cli_paths.check(subcommands(parser)[args.command], args)
    try:
        args.func(args)
    except (*errors(), OSError) as exc:
        print(f"graphdem {args.command}: error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
