"""The options the evaluation's `graphdem` subcommands (evaluate, performance-dem, performance-surrogate) share
beyond surrogate/commands/options.py's: the scene metrics' options and the bootstrap intervals."""

from __future__ import annotations

import argparse


def scene_metric_options(p: argparse.ArgumentParser) -> None:
    """The options of the scene metrics: the landslide body threshold and the article's frame set of Acc."""
    p.add_argument("--body-displacement", type=float, help="landslide body threshold (m); default one mean diameter")
    p.add_argument("--frames", type=int, nargs="+", metavar="TAU",
                   help="the predicted frames (tau = 1 is the first) the article-style Acc averages over, e.g. "
                        "5 10 15 20 30 for the meteorite (article Table 2); default: every predicted frame")


def intervals(args):
    """The bootstrap of --intervals-json (the config's ``intervals`` keys), or None: the config's defaults."""
    from evaluation.metrics.scores import Intervals
    if args.intervals_json is None:
        return None
    want = {"samples", "level", "seed"}
    if not isinstance(args.intervals_json, dict) or set(args.intervals_json) != want:
        raise SystemExit(f"graphdem evaluate: --intervals-json {args.intervals_json!r}: an object with exactly the "
                         f"keys {', '.join(sorted(want))}")
    return Intervals(**args.intervals_json)
