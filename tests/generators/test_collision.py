"""`graphdem restitution`: the two-sphere restitution of a scene's material at chosen DEM time steps."""

import pandas as pd

from generators import collision, config, scenes
from graphdem import cli


def test_the_scene_pairs_are_its_smallest_moving_sphere_and_its_nominal_one():
    cfg = config.load({"scale": "ci"})["shear"]
    scene = scenes.get("shear")
    setup = scene.settle_setup(scene.packings(cfg)[0])
    pairs = collision.scene_pairs(setup)
    assert pairs["nominal"] == setup.nominal_radius == 0.007
    lo, hi = cfg["radius"]
    assert lo <= pairs["smallest"] < pairs["nominal"] < hi      # the box's spheres (kinematic) are not counted


def test_the_command_passes_the_scene_step_and_fails_a_step_fifteen_times_larger(tmp_path, capsys):
    out = tmp_path / "restitution.csv"
    cli.main(["restitution", "--scene", "shear", "--dt-safety", "0.02", "0.3", "--engines", "lammps",
              "--phases", "2", "--set", "scale=ci", "--out", str(out)])
    table = pd.read_csv(out)
    assert list(table["pair"]) == ["smallest", "nominal"] * 2 and set(table["engine"]) == {"lammps"}
    fine, coarse = table[table["dt_safety"] == 0.02], table[table["dt_safety"] == 0.3]
    assert fine["passes"].all() and (fine["max_error"] < 0.01).all()      # ~50 steps per contact: within 1 %
    assert not coarse["passes"].any() and (coarse["max_error"] > 0.03).all()     # ~3 steps: off by 5-7 %
    assert (table["max_error"] >= table["median_error"]).all()
    assert (table["dt"] / table["dt_safety"]).nunique() == 1         # one stable limit: the smallest pair's
    assert "passes everywhere: dt_safety 0.02" in capsys.readouterr().out
