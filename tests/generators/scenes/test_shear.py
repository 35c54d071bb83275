"""Direct-shear metrics (Table 4, Fig. 14) on hand-built trajectories with known answers; the load platen's
geometry, the normal stress sweep and the observables (no engine)."""

import math

import numpy as np
import pytest

from generators import config, dem, sweep
from generators.scenes import shear
from generators.scenes.shear import ShearMetrics


def setup():
    """Split plane z_s = 15 mm, band 5 mm. Soil at z = 12, 17, 25 and 14 mm; one box particle."""
    z = np.array([0.012, 0.017, 0.025, 0.014, 0.0])
    kinematic = np.array([False, False, False, False, True])
    truth = np.zeros((3, 5, 3))
    truth[:, :, 2] = z
    truth[:, :, 0] = np.array([0.01, 0.02, 0.03, 0.04, 0.0])
    truth[1:, 4, 0] = 0.5                          # the box moves: it is no soil, never in a set
    return ShearMetrics(kinematic, z, 0.015, 0.005), truth


def test_sets_from_frame_zero_heights():
    metrics, _ = setup()
    sets = metrics.members()
    assert sets["Above"].tolist() == [False, True, False, False, False]
    assert sets["Below"].tolist() == [True, False, False, True, False]
    assert sets["Failure Surface"].tolist() == [True, True, False, True, False]
    assert sets["All"].tolist() == [True, True, True, True, False]


def test_distance_sums_and_means():
    metrics, truth = setup()
    pred = truth.copy()
    pred[:, 0, 0] += 0.003          # Below
    pred[:, 1, 1] += 0.004          # Above
    pred[:, 2, 2] += 0.001          # outside the band
    pred[:, 4, 0] += 1.0            # box: ignored
    d = metrics.compare(pred, truth)
    np.testing.assert_allclose(d["Above sum"], 0.004)
    np.testing.assert_allclose(d["Above mean"], 0.004)
    np.testing.assert_allclose(d["Below sum"], 0.003)
    np.testing.assert_allclose(d["Below mean"], 0.0015)
    np.testing.assert_allclose(d["Failure Surface sum"], 0.007)
    np.testing.assert_allclose(d["Failure Surface mean"], 0.007 / 3)
    np.testing.assert_allclose(d["All sum"], 0.008)
    np.testing.assert_allclose(d["All mean"], 0.002)


def test_mean_x_of_the_soil_only():
    metrics, truth = setup()
    np.testing.assert_allclose(metrics(truth)["Mean x"], 0.025)


def test_blow_up_is_an_infinite_error_and_an_empty_set_is_nan():
    metrics, truth = setup()
    pred = truth.copy()
    pred[2, 3] = np.nan
    d = metrics.compare(pred, truth)
    assert np.isinf(d["All sum"][2]) and np.isfinite(d["All sum"][1])
    narrow = ShearMetrics(metrics.kinematic, metrics.height0, 0.015, 0.0001)
    assert np.isnan(narrow.compare(truth, truth)["Above sum"]).all()


# ---- the load platen, the normal stress sweep and the observables (no engine) ----------------------------


@pytest.fixture
def ci():
    return config.load({"scale": "ci"})["shear"]


def soil_bed(cfg, top=0.025):
    """A square lattice of soil spheres of the largest radius whose top is at ``top``."""
    r = cfg["radius"][1]
    xs = np.arange(r, cfg["box"][0] - r, 2 * r)
    xy = np.stack(np.meshgrid(xs, xs, indexing="ij"), -1).reshape(-1, 2)
    xyz = np.column_stack([xy, np.full(len(xy), top - r)])
    return dem.Particles(xyz, np.full(len(xy), r), np.full(len(xy), shear.SOIL), {shear.LOWER: np.zeros(len(xy), bool)})


def test_platen_grid_lies_inside_the_frame_clear_of_the_walls(ci):
    xy = shear.platen_grid(ci)
    length, width, _ = ci["box"]
    rw = ci["wall_radius"]
    gap = shear.PLATEN_CLEARANCE * rw
    assert np.isclose((xy - rw).min(), gap) and np.isclose(length - (xy[:, 0] + rw).max(), gap)
    assert np.isclose(width - (xy[:, 1] + rw).max(), gap)
    n = int(math.ceil((length - 2 * (1 + shear.PLATEN_CLEARANCE) * rw) / (ci["wall_spacing"] * rw))) + 1
    assert len(xy) == n * n == 64
    step = np.diff(np.unique(xy[:, 0]))
    assert step.max() <= ci["wall_spacing"] * rw + 1e-12         # holes smaller than the smallest soil sphere


def test_platen_rests_on_the_highest_soil_without_overlap(ci):
    bed = soil_bed(ci)
    bump = dem.Particles(np.array([[0.05, 0.05, 0.028]]), np.array([0.007]), np.array([shear.SOIL]),
                         {shear.LOWER: np.array([False])})
    soil = bed.concat(bump)
    platen = shear.platen_particles(ci, soil)
    assert (platen.species == shear.PLATEN).all() and np.allclose(platen.radius, ci["wall_radius"])
    assert np.ptp(platen.x[:, 2]) == 0.0
    d = np.linalg.norm(platen.x[:, None] - soil.x[None], axis=-1) - platen.radius[:, None] - soil.radius[None]
    assert d.min() == pytest.approx(0.0, abs=1e-12)               # touching, not overlapping
    assert platen.x[0, 2] - ci["wall_radius"] > 0.025 - 1e-12    # above the flat bed


def test_loaded_packing_groups_and_species(ci):
    box = shear.box_particles(ci, ci["box"][2])
    packing = box.concat(soil_bed(ci))
    full = shear.loaded(packing, dict(ci, normal_stress=1e4, domain_displacement=0.006))
    species = full.species
    assert set(np.unique(species)) == {shear.BOX, shear.SOIL, shear.PLATEN}
    assert shear.SCENE.species == {0: "box", 1: "soil", 2: "platen"}
    assert shear.SCENE.kinematic_species == (shear.BOX, shear.PLATEN)
    g = full.groups
    assert np.array_equal(g[shear.PLATEN_GROUP], species == shear.PLATEN)
    assert np.array_equal(g[shear.LOWER] | g[shear.UPPER], species == shear.BOX)
    assert not (g[shear.LOWER] & g[shear.UPPER]).any()
    assert (full.x[g[shear.UPPER], 2] >= shear.split_height(ci)).all()


def test_the_flanges_cover_the_gaps_the_shear_opens(ci):
    """At the split plane the trailing flange (lower half) reaches back from x = 0 by the largest displacement and
    the leading flange (upper half) out from x = L: after any displacement up to it, no hole in the plates (between
    four neighbours) or between a plate and its box wall passes the smallest soil sphere, and both span the width."""
    row = dict(ci, domain_displacement=0.012)
    f = shear.flanges(row)
    rw, (length, width, _), zs = ci["wall_radius"], ci["box"], shear.split_height(ci)
    trailing, leading = f.x[f.groups[shear.LOWER]], f.x[~f.groups[shear.LOWER]]
    assert np.allclose(trailing[:, 2], zs - rw) and np.allclose(leading[:, 2], zs + rw)
    assert trailing[:, 0].max() < -rw and trailing[:, 0].min() == pytest.approx(-rw - 0.012)
    assert leading[:, 0].min() > length + rw and leading[:, 0].max() == pytest.approx(length + rw + 0.012)
    for plate, wall_x in ((trailing, -rw), (leading, length + rw)):
        xs, ys = np.unique(np.append(plate[:, 0], wall_x)), np.unique(plate[:, 1])
        assert ys.min() == pytest.approx(-rw) and ys.max() == pytest.approx(width + rw)
        hole = math.hypot(np.diff(xs).max(), np.diff(ys).max()) - 2 * rw
        assert hole < 2 * ci["radius"][0]
    lo, hi = shear.domain(row, 0.012)
    assert (f.x >= lo).all() and (f.x <= hi).all()


def test_platen_force_counts_its_weight_in_the_load(ci):
    row = dict(ci, normal_stress=2.0e4)
    area = ci["box"][0] * ci["box"][1]
    force = shear.platen_force(row)
    assert force < 0
    assert -force + ci["platen_mass"] * ci["gravity"] == pytest.approx(2.0e4 * area)


def test_sweep_crosses_modulus_and_normal_stress(ci):
    table = sweep.build("shear", ci)
    assert len(table) == 2 * 2 * len(ci["sweep"]["displacements"])
    assert sorted(set(table["normal_stress"])) == [5.0e3, 5.0e4]
    assert sorted(set(table["young"])) == [1.0e7, 1.0e8]
    assert shear.SCENE.properties(table.iloc[0].to_dict()) == {"young": 1.0e7, "normal_stress": 5.0e3}
    assert shear.SCENE.log_scaled_properties == ("young", "normal_stress")


def test_a_platen_heavier_than_the_smallest_load_is_refused(ci):
    from generators.config import ConfigError
    heavy = dict(ci, platen_mass=10.0)
    with pytest.raises(ConfigError, match="platen_mass"):
        shear.SCENE.check(heavy)
    shear.SCENE.check(ci)


def test_observables_from_group_forces_and_positions(ci):
    """Upper frame and platen x forces add to the shear force; the platen's z force over L W is the normal stress."""
    groups = {shear.LOWER: np.array([True, False, False, False]), shear.UPPER: np.array([False, True, False, False]),
              shear.PLATEN_GROUP: np.array([False, False, True, True])}
    position = np.zeros((3, 4, 3))
    position[:, 0, 0] = [0.0, 0.001, 0.002]
    position[:, 2:, 2] = np.array([0.03, 0.0299, 0.0301])[:, None]
    upper = np.array([[0.0, 0, 0], [5.0, 1, 0], [7.0, 0, 0]])
    platen = np.array([[0.0, 0, 100.0], [1.0, 0, 90.0], [-1.0, 0, 110.0]])
    out = shear.observables(ci, position, {shear.UPPER: upper, shear.PLATEN_GROUP: platen}, groups)
    area = ci["box"][0] * ci["box"][1]
    np.testing.assert_allclose(out["shear_force"], [0.0, 6.0, 6.0])
    np.testing.assert_allclose(out["shear_stress"], np.array([0.0, 6.0, 6.0]) / area)
    np.testing.assert_allclose(out["shear_displacement"], [0.0, 0.001, 0.002])
    np.testing.assert_allclose(out["normal_stress"], np.array([100.0, 90.0, 110.0]) / area)
    np.testing.assert_allclose(out["normal_displacement"], [0.0, -0.0001, 0.0001], atol=1e-12)


def test_peak_shear_stress():
    tau = np.array([0.0, 1.0, 5.0, 2.0, 3.0])
    assert shear.peak_shear_stress(tau) == 5.0
    assert shear.peak_shear_stress(tau, smooth=3) == pytest.approx(10.0 / 3)
    assert math.isnan(shear.peak_shear_stress(np.array([np.nan, np.nan])))


def test_dem_peak_shear_stress_metric_from_the_observables():
    from types import SimpleNamespace
    traj = SimpleNamespace(observables={"shear_stress": np.array([0.0, 2.0e3, 4.0e3, 3.0e3])},
                           parameters={"normal_stress": 1.0e4})
    assert ShearMetrics.dem_values(traj) == {"Peak shear stress": 4.0e3, "Peak stress ratio": 0.4}
    old = SimpleNamespace(observables={}, parameters={})
    assert all(math.isnan(v) for v in ShearMetrics.dem_values(old).values())
    from generators import crosscheck
    assert crosscheck.metric_names("shear")[-2:] == ("Peak shear stress", "Peak stress ratio")
    assert crosscheck.metric_names("meteorite") == tuple(__import__("generators.scenes.meteorite",
                                                                    fromlist=["SCENE"]).SCENE.metrics.names)


# ---- quasi-static loading: the inertial number (docs/scenes/shear.md, "Quasi-static loading") -----------------

def test_inertial_number_by_hand(ci):
    """I = (v / H) d sqrt(rho / sigma_n): 0.1 m/s over H = 30 mm, d = 2 x 7 mm (ci radii 6-8 mm), rho = 2650,
    5 kPa: 3.333 x 0.014 x 0.7280 = 0.03397."""
    assert shear.mean_diameter(ci) == pytest.approx(0.014)
    assert shear.inertial_number(ci, 0.1, 5.0e3) == pytest.approx(0.1 / 0.03 * 0.014 * math.sqrt(2650.0 / 5.0e3))
    assert shear.inertial_number(ci, 0.1, 5.0e3) == pytest.approx(0.03397, rel=1e-3)


@pytest.fixture
def default():
    return config.load({"scale": "default"})["shear"]


def test_the_default_derives_each_sims_speed_at_the_inertial_number_limit(default):
    """Null shear_speed: v = I_max H sqrt(sigma_n / rho) / d, so I = max_inertial_number = 1e-3 exactly; a
    stiffer load shears faster (sqrt(10) per decade of sigma_n)."""
    assert default["shear_speed"] is None and default["max_inertial_number"] == 1.0e-3
    speeds = [shear.target_speed(default, s) for s in shear.normal_stress_values(default)]
    for stress, speed in zip(shear.normal_stress_values(default), speeds, strict=True):
        assert shear.inertial_number(default, speed, stress) == pytest.approx(1.0e-3, rel=1e-12)
    assert speeds[-1] / speeds[0] == pytest.approx(math.sqrt(10.0))
    assert speeds[0] == pytest.approx(1.0e-3 * 0.03 * math.sqrt(5.0e3 / 2650.0) / 0.008)
    assert shear.slowest_speed(default) == speeds[0]


def test_every_default_sim_shears_at_most_at_the_limit_in_whole_force_samples(default):
    """The recorded frame's steps (a whole number of FORCE_SAMPLES) give the sim's displacement over its frames
    at an inertial number at most the limit, and within one rounding step of it."""
    for row in sweep.build("shear", default).to_dict("records"):
        dt = shear.dem_step(row, "test")[0]
        every = shear.frame_steps(row, dt)
        assert every % shear.FORCE_SAMPLES == 0
        speed = row["displacement"] / (every * dt * (row["frames"] - 1))
        value = shear.inertial_number(row, speed, row["normal_stress"])
        assert value <= row["max_inertial_number"]
        assert value > row["max_inertial_number"] * (1 - shear.FORCE_SAMPLES / every * 1.01)


def test_frame_steps_round_up_where_the_nearest_would_shear_too_fast(default):
    """The nearest whole multiple of FORCE_SAMPLES steps below the exact interval shears faster than the
    limit: one multiple more is taken. An explicit speed within the limit keeps the nearest (the ci scale's)."""
    row = dict(sweep.build("shear", default).iloc[0].to_dict())
    speed = shear.target_speed(row, row["normal_stress"])
    interval = row["displacement"] / (speed * (row["frames"] - 1))
    dt = interval / (shear.FORCE_SAMPLES * 40.4)           # the exact interval: 40.4 multiples; the nearest 40
    assert shear.frame_steps(row, dt) == 41 * shear.FORCE_SAMPLES
    dt = interval / (shear.FORCE_SAMPLES * 40.6)           # the nearest, 41, is already slower
    assert shear.frame_steps(row, dt) == 41 * shear.FORCE_SAMPLES
    explicit = dict(row, shear_speed=0.5 * speed)
    dt = interval / (shear.FORCE_SAMPLES * 40.4) * 2        # at half the speed: 40.4 multiples again, 40 kept
    assert shear.frame_steps(explicit, dt) == 40 * shear.FORCE_SAMPLES


def test_an_explicit_speed_above_the_limit_is_refused_naming_both_keys(default):
    from generators.config import ConfigError
    with pytest.raises(ConfigError, match=r"'shear.shear_speed' = 0.1 m/s.*I = 0.0194.*5000 Pa.*"
                                          r"'shear.max_inertial_number' = 0.001.*at most 0.00515 m/s"):
        config.load({"scale": "default", "shear": {"shear_speed": 0.1}})
    cfg = config.load({"scale": "default", "shear": {"shear_speed": 0.005}})["shear"]
    assert shear.inertial_number(cfg, 0.005, 5.0e3) < 1.0e-3
    faster = config.load({"scale": "default", "shear": {"shear_speed": 0.1, "max_inertial_number": 0.05}})
    assert faster["shear"]["shear_speed"] == 0.1


def test_a_max_inertial_number_out_of_range_is_refused():
    from generators.config import ConfigError
    for bad in (0.0, -1.0e-3, 2.0):
        with pytest.raises(ConfigError, match="max_inertial_number"):
            config.load({"scale": "default", "shear": {"max_inertial_number": bad}})
