"""The stability stage's DEM test on a tiny slide: a step above the stable limit blows up, named, leaving nothing."""

import pytest

from generators import config, engine, stability, sweep
from generators.scenes import slide

pytestmark = pytest.mark.engine


def test_time_steps_above_the_limit_blow_up_named_and_leave_nothing(tmp_path):
    cfg = config.load({"scale": "ci", "slide": {"n_sims": 3, "settle_time": 4.0, "frames": 5, "model": {"history": 2},
                                                "frame_interval": 0.1, "record_start": 0.3}})["slide"]
    row = sweep.build("slide", cfg).to_dict("records")[0]
    engine.prepare(slide.SCENE, "lammps", slide.SCENE.packing_params(cfg, 0), tmp_path / "packing")
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    report = stability.dem_time_steps("slide", row, tmp_path / "packing", [0.5, 8.0], scratch)
    calm, wild = report.to_dict("records")
    assert calm["stable"] and calm["dt"] == pytest.approx(0.5 * calm["dt_limit"]) and calm["cause"] == ""
    assert calm["max_overlap"] < cfg["max_overlap"]
    assert not wild["stable"] and wild["sim"] == row["id"] and wild["frame"] >= 0
    assert "particles left the domain" in wild["cause"] or "overlap" in wild["cause"] or "energy" in wild["cause"]
    assert wild["left_behind"] == 0 and list(scratch.iterdir()) == []


def test_unknown_scene_is_refused(tmp_path):
    with pytest.raises(ValueError, match="unknown scene 'dune'; known: collapse, meteorite, shear, slide"):
        stability.dem_time_steps("dune", {}, tmp_path, [1.0], tmp_path)
