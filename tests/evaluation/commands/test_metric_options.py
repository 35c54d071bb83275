"""The scene metrics' options and the bootstrap intervals of --intervals-json (evaluation/commands/
metric_options.py)."""

import argparse
import json

import pytest

from evaluation.commands import metric_options
from evaluation.metrics.scores import Intervals


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser()
    metric_options.scene_metric_options(p)
    p.add_argument("--intervals-json", type=json.loads, default=None)
    return p


def test_the_scene_metric_options_parse_to_numbers():
    args = _parser().parse_args(["--body-displacement", "0.002", "--frames", "5", "10", "30"])
    assert args.body_displacement == 0.002 and args.frames == [5, 10, 30]
    args = _parser().parse_args([])
    assert args.body_displacement is None and args.frames is None


def test_intervals_are_the_config_s_three_keys_or_none():
    assert metric_options.intervals(_parser().parse_args([])) is None
    args = _parser().parse_args(["--intervals-json", '{"samples": 200, "level": 0.9, "seed": 3}'])
    assert metric_options.intervals(args) == Intervals(samples=200, level=0.9, seed=3)
    for bad in ('{"samples": 200, "level": 0.9}', '[200, 0.9, 3]'):
        with pytest.raises(SystemExit, match="an object with exactly the keys level, samples, seed"):
            metric_options.intervals(_parser().parse_args(["--intervals-json", bad]))
    with pytest.raises(ValueError, match="intervals.level = 1.5"):
        metric_options.intervals(_parser().parse_args(["--intervals-json",
                                                       '{"samples": 200, "level": 1.5, "seed": 3}']))
