"""The options several subcommands share (surrogate/commands/options.py): a device setting checked as it is parsed,
the runtime switches of --runtime-json (required where a command needs them) and tables written whole."""

import argparse
import json

import pandas as pd
import pytest

from generators import config
from surrogate import runtime
from surrogate.commands import options


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser()
    options.checkpoint_and_data(p, data_required=False)
    return p


def test_a_device_setting_is_checked_as_it_is_parsed():
    for value in ("auto", "cpu", "cuda", "cuda:1"):
        assert options.device_arg(value) == value
    for value in ("gpu", "cuda:x", ""):
        with pytest.raises(argparse.ArgumentTypeError, match="allowed are"):
            options.device_arg(value)
    assert _parser().parse_args(["--checkpoint", "b.pt"]).device == "auto"


def test_the_runtime_switches_or_none_unless_a_command_needs_them():
    args = _parser().parse_args(["--checkpoint", "b.pt"])
    assert options.runtime_config(args) is None
    with pytest.raises(SystemExit, match="graphdem rollout: --runtime-json is required"):
        options.runtime_config(args, required_by="rollout")
    switches = config.load({"scale": "ci"})["slide"]["runtime"]
    args = _parser().parse_args(["--checkpoint", "b.pt", "--runtime-json", json.dumps(switches)])
    assert options.runtime_config(args) == runtime.Runtime.from_config(switches)


def test_tables_are_written_whole(tmp_path):
    options.write_rows([{"a": 1, "b": 2.5}, {"a": 3, "b": None}], tmp_path / "rows.csv")
    assert (tmp_path / "rows.csv").read_text() == "a,b\n1,2.5\n3,\n"
    options.write_table(pd.DataFrame({"x": [1.0, float("nan")]}), tmp_path / "t.csv", na_rep="NaN")
    assert (tmp_path / "t.csv").read_text() == "x\n1.0\nNaN\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rows.csv", "t.csv"]          # no temporary left
