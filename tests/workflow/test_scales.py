"""One scale per results folder: the stamp, the refusal and its message, the override."""

import pytest

from graphdem_workflow import scales


def test_a_folder_without_a_stamp_takes_any_scale(tmp_path):
    assert scales.recorded(tmp_path / "slide") is None
    scales.check(tmp_path / "slide", "ci")


def test_the_recorded_scale_is_read_back(tmp_path):
    scales.record(tmp_path / "slide", "paper")
    assert scales.recorded(tmp_path / "slide") == "paper"
    assert (tmp_path / "slide" / "scale.txt").read_text() == "paper\n"
    assert [p.name for p in (tmp_path / "slide").iterdir()] == ["scale.txt"]     # no temporary left


def test_another_scale_is_refused_naming_both_scales_and_every_way_on(tmp_path):
    scales.record(tmp_path / "slide", "default")
    scales.check(tmp_path / "slide", "default")                  # the same scale runs
    with pytest.raises(scales.ScaleConflict) as err:
        scales.check(tmp_path / "slide", "ci")
    message = str(err.value)
    assert "scale=default" in message and "scale=ci" in message and str(tmp_path / "slide") in message
    assert "snakemake -d runs/ci" in message and "--config overwrite_scale=true" in message


def test_the_override_replaces(tmp_path):
    scales.record(tmp_path / "slide", "default")
    scales.check(tmp_path / "slide", "ci", overwrite=True)
