"""A `graphdem` subcommand's arguments parsed by its own module's ``register`` alone (as graphdem/cli.py does for
all of them), for the tests of the command modules."""

from __future__ import annotations

import argparse


def parse(register, argv: list[str]) -> argparse.Namespace:
    """``argv`` (the subcommand's name first) parsed by the subparsers ``register`` adds."""
    parser = argparse.ArgumentParser(prog="graphdem")
    register(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(argv)


def run(register, argv: list[str]) -> argparse.Namespace:
    """``argv`` parsed as :func:`parse` does, then run by the function the subcommand set; its arguments. The
    torch thread count a command sets (its --threads) is given back afterwards, so that no later test of the
    same process computes with it."""
    import torch

    args = parse(register, argv)
    threads = torch.get_num_threads()
    try:
        args.func(args)
    finally:
        torch.set_num_threads(threads)
    return args
