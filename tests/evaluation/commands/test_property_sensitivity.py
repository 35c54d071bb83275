"""`graphdem property-sensitivity` (evaluation/commands/property_sensitivity.py): the sims and their DEM ensemble reruns
come together or not at all."""

import pytest

from evaluation.commands import property_sensitivity

from ...command_line import parse, run


def _argv(tmp_path, *extra):
    return ["property-sensitivity", "--checkpoint", str(tmp_path / "best.pt"), "--runs", str(tmp_path / "low"),
            str(tmp_path / "high"), "--sims", "shear_0001", "--property", "young", "--history", "6",
            "--out", str(tmp_path / "p.csv"), *extra]


@pytest.mark.parametrize("extra", [["--ensemble", "e"], ["--sims-dir", "s"]])
def test_the_ensemble_needs_the_sims_and_the_sims_the_ensemble(tmp_path, extra):
    with pytest.raises(SystemExit, match="give --sims-dir and --ensemble together"):
        run(property_sensitivity.register, _argv(tmp_path, *extra))
    assert not (tmp_path / "p.csv").exists()


def test_the_options_parse_to_the_runs_and_the_tolerance(tmp_path):
    args = parse(property_sensitivity.register, _argv(tmp_path))
    assert args.runs == [tmp_path / "low", tmp_path / "high"] and args.tolerance == 0.25 and args.history == 6
