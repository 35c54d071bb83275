"""The granular column collapse: its metrics (runout of the continuous mass, height, deposit profile and its
deviation) on a hand-built deposit, the runout-law fit on a table that follows the laws exactly, the column and
floor it builds, the DEM setups of both stages, and the check that the window covers the collapse."""

import math

import numpy as np
import pandas as pd
import pytest

from generators import config, dem, h5md, sweep
from generators.errors import ConfigError
from generators.scenes import collapse

# The hand-built deposit: grains of radius 0.5 (bins of one mean diameter: 1.0), L0 = 2, a floor of discs of
# radius 0.25 (its top at 0.5) that the metrics leave out.
L0, FLOOR_R, R = 2.0, 0.25, 0.5
FLOOR = np.array([[0.25, 0.25], [0.7, 0.25]])
COLUMN = np.array([[0.5, 1.0], [1.5, 1.0], [0.5, 2.0], [1.5, 2.0]])     # 2 x 2 grains behind the gate
DEPOSIT = np.array([[0.5, 1.0], [1.5, 1.0], [2.5, 1.0], [4.5, 1.0]])    # spread out; the last rolled away ahead


def _frames(*grains) -> np.ndarray:
    return np.stack([np.vstack([FLOOR, g]) for g in grains])


def _metrics() -> collapse.CollapseMetrics:
    kinematic = np.array([True, True, False, False, False, False])
    radius = np.r_[np.full(2, FLOOR_R), np.full(4, R)]
    return collapse.CollapseMetrics(kinematic, radius, L0, 2 * FLOOR_R)


def test_runout_is_the_front_of_the_continuous_mass_and_height_the_highest_grain_top():
    m = _metrics()
    assert m.bin_width == 1.0
    values = m(_frames(COLUMN, DEPOSIT))
    # column: bins 0 and 1 full, the first gap at bin 2 -> front 2, runout 2 - L0 = 0; top 2.0 + 0.5 - floor 0.5
    # deposit: bins 0, 1, 2 full, bin 3 empty (the grain in bin 4 does not count) -> front 3, runout 1; top 1.5 - 0.5
    np.testing.assert_allclose(values["Runout"], [0.0, 1.0])
    np.testing.assert_allclose(values["Height"], [2.0, 1.0])
    broken = DEPOSIT.copy()
    broken[3] = np.nan
    assert np.isnan(m(_frames(broken))["Runout"][0])                # a non-finite grain: no runout


def test_the_profile_is_the_highest_grain_top_above_the_floor_per_bin():
    profile = _metrics().profile(_frames(COLUMN, DEPOSIT))
    np.testing.assert_allclose(profile, [[2.0, 2.0, np.nan, np.nan, np.nan], [1.0, 1.0, 1.0, np.nan, 1.0]])


def test_profile_deviation_averages_over_the_bins_either_profile_fills():
    m = _metrics()
    raised, moved = DEPOSIT.copy(), DEPOSIT.copy()
    raised[2, 1] += 0.4         # bin 2 is 0.4 higher: 0.4 over the 4 filled bins (0, 1, 2, 4)
    moved[3, 0] = 6.5           # the lone grain in bin 6, not 4: 1.0 + 1.0 over 5 bins (0, 1, 2, 4, 6)
    dev = m.compare(_frames(COLUMN, raised, moved), _frames(COLUMN, DEPOSIT, DEPOSIT))["Profile dev"]
    np.testing.assert_allclose(dev, [0.0, 0.4 / 4, 2.0 / 5])
    broken = DEPOSIT.copy()
    broken[0, 0] = np.inf
    assert m.compare(_frames(broken), _frames(DEPOSIT))["Profile dev"][0] == np.inf


def _trajectory(grains: list[np.ndarray], parameters: dict) -> h5md.Trajectory:
    position = _frames(*grains)
    n = position.shape[1]
    kinematic = np.arange(n) < 2
    return h5md.Trajectory(position=position, time=0.1 * np.arange(len(grains)), step=100 * np.arange(len(grains)),
                           species=np.where(kinematic, collapse.FLOOR, collapse.GRAIN),
                           radius=np.where(kinematic, FLOOR_R, R), mass=np.ones(n), kinematic=kinematic,
                           box_lower=np.zeros(2), box_upper=np.array([10.0, 5.0]), parameters=parameters)


def test_metrics_of_a_trajectory_read_the_column_width_and_floor_from_its_parameters():
    traj = _trajectory([COLUMN, DEPOSIT], {"column_width": L0, "floor_radius": FLOOR_R})
    m = collapse.CollapseMetrics.for_trajectory(traj)
    assert (m.column_width, m.floor) == (L0, 2 * FLOOR_R)
    np.testing.assert_array_equal(m.kinematic, traj.kinematic)
    with pytest.raises(ValueError, match=r"collapse metrics need the parameters \['floor_radius'\]"):
        collapse.CollapseMetrics.for_trajectory(_trajectory([COLUMN, DEPOSIT], {"column_width": L0}))


def _law_table() -> pd.DataFrame:
    """Runouts on 1.5 a below a = 1.8 and on 2 a^(2/3) above 2.8, heights on 0.8 a^0.5: friction 0.3 over six
    aspect ratios, 0.6 over two (one in each regime)."""
    rows = []
    for mu, aspects in ((0.3, [0.5, 1.0, 1.5, 3.0, 5.0, 8.0]), (0.6, [1.0, 4.0])):
        for a in aspects:
            runout = 1.5 * a if a < 1.8 else 2.0 * a ** (2 / 3)
            rows.append({"sim": f"s{mu}_{a}", "friction": mu, "aspect": a, "runout": runout, "height": 0.8 * a**0.5})
    return pd.DataFrame(rows)


def test_the_runout_fit_recovers_the_laws_the_table_follows():
    fits = collapse.fit_runout(_law_table()).set_index("friction")
    assert list(fits.index) == ["all", "0.3", "0.6"] and set(fits["sim"]) == {"fit"}
    for name in ("all", "0.3"):
        assert fits.loc[name, "linear_prefactor"] == pytest.approx(1.5)
        assert fits.loc[name, "power_prefactor"] == pytest.approx(2.0)
        assert fits.loc[name, "power_exponent"] == pytest.approx(2 / 3)
        assert fits.loc[name, "height_exponent"] == pytest.approx(0.5)
    assert (fits.loc["all", "n_small"], fits.loc["all", "n_large"]) == (4, 4)
    # friction 0.6: one sim per regime, a linear prefactor but too few for either power law
    assert fits.loc["0.6", "linear_prefactor"] == pytest.approx(1.5)
    assert np.isnan(fits.loc["0.6", "power_prefactor"]) and np.isnan(fits.loc["0.6", "height_exponent"])


def test_physics_measures_the_aspect_on_the_settled_column_the_final_runout_and_whether_it_rests(tmp_path):
    trajectories = []
    for k, shift in enumerate((0.0, 0.2)):
        last = DEPOSIT + [shift, 0.0]          # the second sim still moves: 0.2 m in the last 0.1 s
        trajectories.append(_trajectory([COLUMN, DEPOSIT, DEPOSIT, last], {
            "column_width": L0, "floor_radius": FLOOR_R, "friction": 0.4, "id": f"c{k}", "gravity": 10.0}))
    table = collapse.SCENE.physics(trajectories, tmp_path / "runout.csv", tmp_path / "runout.png",
                                   {"settle_speed": 0.05})
    sims = table[table["sim"] != "fit"].set_index("sim")
    # aspect = frame 0 height / L0 = 2 / 2; runout and height of the last frame / L0; speed = 0.2 m / 0.1 s
    np.testing.assert_allclose(sims["aspect"], [1.0, 1.0])
    np.testing.assert_allclose(sims["column_diameters"], [2.0, 2.0])        # L0 = 2 of grains 1.0 across
    np.testing.assert_allclose(sims["runout"], [1.0 / L0, 1.0 / L0])   # the shift keeps the bins
    np.testing.assert_allclose(sims["height"], [0.5, 0.5])
    np.testing.assert_allclose(sims["final_max_speed"], [0.0, 2.0])
    np.testing.assert_allclose(sims["final_rms_speed"], [0.0, 2.0])    # every grain moved 0.2 m in 0.1 s
    # c0 rests from t = 0.1 (the interval 0.1-0.2 is still); in units of sqrt(H0 / g) = sqrt(2 / 10)
    assert list(sims["at_rest"]) == [True, False]
    assert sims.loc["c0", "rest_time"] == pytest.approx(0.1)
    assert sims.loc["c0", "rest_time_scaled"] == pytest.approx(0.1 / math.sqrt(0.2))
    assert np.isnan(sims.loc["c1", "rest_time"])
    # only the sim at rest is fitted (runout 0.5 at a = 1): lambda 0.5; the moving one is counted
    fit = table[(table["sim"] == "fit") & (table["friction"] == "all")].iloc[0]
    assert fit["linear_prefactor"] == pytest.approx(0.5) and fit["n_small"] == 1 and fit["n_moving"] == 1
    assert pd.read_csv(tmp_path / "runout.csv").shape == table.shape
    assert (tmp_path / "runout.png").read_bytes()[:4] == b"\x89PNG"


def test_the_rest_time_is_where_the_rms_speed_stays_below_the_settling_speed():
    time = np.arange(5) * 0.5
    one = np.array([0.0, 1.0, 1.2, 1.2, 1.2])       # one grain: speeds 2, 0.4, 0, 0 m/s
    position = np.stack([one, np.zeros(5)], axis=-1)[:, None, :]
    rms, rest_time = collapse.rest(time, position, speed=0.5)
    np.testing.assert_allclose(rms, [2.0, 0.4, 0.0, 0.0])
    assert rest_time == pytest.approx(0.5)          # below 0.5 m/s from the interval starting at t = 0.5
    assert collapse.rest(time, position, speed=0.3)[1] == pytest.approx(1.0)
    back = position.copy()
    back[-1, 0, 0] = 1.0                             # moves again in the last interval: not at rest
    assert np.isnan(collapse.rest(time, back, speed=0.3)[1])
    assert collapse.rest(time, np.zeros((5, 1, 2)), speed=0.3)[1] == 0.0   # never moved: at rest from the start


def test_aspect_ratios_are_log_spaced():
    cfg = {"sweep": {"aspect": [0.5, 4.0], "n_aspects": 3}}
    assert collapse.aspects(cfg) == [0.5, float(f"{math.sqrt(2):.6g}"), 4.0]     # 0.5 x (2 sqrt 2)^k
    cfg["sweep"]["n_aspects"] = 1
    assert collapse.aspects(cfg) == [float(f"{math.sqrt(0.5 * 4.0):.6g}")]       # the geometric mean


def test_the_floor_is_a_row_of_fixed_discs_on_the_ground():
    r, length = 0.002, 0.1
    floor = collapse.floor_particles({"floor_radius": r}, length)
    # centres at r, 2.8 r, 4.6 r, ... below the length: ceil((length - r) / 1.8 r) = ceil(27.2) = 28 discs
    assert len(floor.x) == 28
    np.testing.assert_allclose(np.diff(floor.x[:, 0]), 1.8 * r)
    np.testing.assert_allclose(floor.x[:, 1], r)
    assert set(floor.species) == {collapse.FLOOR} and np.all(floor.radius == r)


def test_the_loose_column_has_no_overlaps_and_repeats_with_its_seed():
    cfg = {"radius": [0.0018, 0.0022], "floor_radius": 0.002, "column_width": 0.024}
    a = collapse.loose_column(cfg, 2.0, [1, 2])
    # lattice spacing s >= 2 r_max and each grain moves at most 0.9 (s / 2 - r): two neighbours stay at least
    # 0.1 s + 0.9 (r_i + r_j) >= r_i + r_j apart
    gaps = np.linalg.norm(a.x[:, None] - a.x[None], axis=-1) - (a.radius[:, None] + a.radius[None])
    assert np.all(gaps[~np.eye(len(a.x), dtype=bool)] >= 0)
    assert np.all((a.radius >= 0.0018) & (a.radius <= 0.0022)) and set(a.species) == {collapse.GRAIN}
    assert a.x[:, 1].max() < collapse.floor_top(cfg) + collapse.FILL * 2.0 * 0.024
    np.testing.assert_array_equal(collapse.loose_column(cfg, 2.0, [1, 2]).x, a.x)
    assert len(collapse.loose_column(cfg, 1.0, [1, 2]).x) < len(a.x)        # a lower column, fewer grains


@pytest.fixture
def ci() -> dict:
    return config.load({"scale": "ci"})["collapse"]


def test_the_settling_column_stands_between_the_back_wall_and_the_gate(ci):
    params = collapse.SCENE.packings(ci)[0]
    setup = collapse.SCENE.settle_setup(params)
    assert setup.walls == (dem.PlanarWall(0, 0.0, ci["column_width"]),)
    grains = setup.particles.species == collapse.GRAIN
    assert np.all(setup.kinematic == ~grains)
    assert setup.particles.x[grains, 0].max() < ci["column_width"]
    assert isinstance(setup.schedule, dem.Settle) and setup.schedule.speed == ci["settle_speed"]


def test_the_released_column_keeps_its_grains_on_a_floor_over_the_whole_domain(ci):
    row = sweep.build("collapse", ci).to_dict("records")[0]
    packing = collapse.SCENE.settle_setup(collapse.SCENE.packings(ci)[0]).particles
    setup = collapse.SCENE.simulate_setup(row, packing)
    grains = setup.particles.species == collapse.GRAIN
    np.testing.assert_array_equal(setup.particles.x[grains], packing.x[packing.species == collapse.GRAIN])
    floor = setup.particles.x[~grains]
    length = row["domain"][0]
    assert floor[:, 0].max() > length - 1.8 * ci["floor_radius"] and floor[:, 0].max() < length
    assert setup.walls == (dem.PlanarWall(0, 0.0, float(length)),)           # the gate gone, an end wall far off
    s = setup.schedule
    assert (s.start, s.frames) == (0, ci["frames"]) and s.every == round(ci["frame_interval"] / setup.dt)
    assert setup.max_energy_gain == ci["max_energy_gain"]


def test_a_window_shorter_than_the_tallest_collapse_is_refused(ci):
    collapse.SCENE.check(ci)
    # the tallest column (a = 4, L0 = 0.024 m) rests after rest_time 3 x sqrt(4 x 0.024 / 9.81) = 0.297 s; 10
    # frames of 0.025 s record 0.225 s
    with pytest.raises(ConfigError, match=r"'collapse.frames' = 10 .* record 0.225 s; .*'collapse.rest_time' = 3 "
                                          r"sqrt\(H0/g\) = 0.297 s: record longer"):
        collapse.SCENE.check({**ci, "frames": 10})
    # the default and the paper preset record at least their rest_time of 5.5 sqrt(H0/g) of the tallest column
    for scale in ("default", "paper"):
        cfg = config.load({"scale": scale})["collapse"]
        tallest = math.sqrt(max(cfg["sweep"]["aspect"]) * cfg["column_width"] / cfg["gravity"])
        assert cfg["rest_time"] == 5.5 and cfg["frame_interval"] * (cfg["frames"] - 1) >= 5.5 * tallest


def test_the_rest_time_is_a_check_of_the_config_not_a_parameter_of_the_sims(ci):
    rows = sweep.build("collapse", ci)
    assert "rest_time" not in rows.columns and "dt_safety" in rows.columns
    # the paper preset: columns 25 mean diameters wide, at least 5 aspect ratios above 3
    paper = config.load({"scale": "paper"})["collapse"]
    assert paper["column_width"] / sum(paper["radius"]) == pytest.approx(25.0)
    assert sum(a > 3.0 for a in collapse.aspects(paper)) >= 5
