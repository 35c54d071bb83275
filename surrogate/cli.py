"""The `graphdem` command under its former module name: ``python -m surrogate.cli`` (how torchrun starts the
train stage's processes, generators/launch.py) and ``surrogate.cli.main`` run graphdem/cli.py, where the
command and its list of registrars live; the surrogate's subcommands are in surrogate/commands/."""

import sys

from graphdem.cli import REGISTRARS, build_parser, errors, main

__all__ = ["REGISTRARS", "build_parser", "errors", "main"]

if __name__ == "__main__":
    sys.exit(main())
