"""The DEM ensemble's members (generators/ensemble.py): the size of the displacement, its draw, and the runs of
both engines replayed to the last history frame and perturbed there."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from generators import config, contact, convert, dem, engine, engines, ensemble, h5md, sweep
from generators.scenes import slide

ENGINES = engines.NAMES          # every registered engine (generators/engines.py)
RADIUS, DENSITY, G = 0.01, 2650.0, 9.81


# ---- the size rule -----------------------------------------------------------------------------------------------


def test_the_float32_floor_is_half_the_float32_spacing_at_the_largest_box_coordinate():
    # 100 m lies in [64, 128): float32 steps of 2^-17 m there, half of it 2^-18 m
    assert ensemble.float32_floor([0.0, 0.0], [100.0, 80.0]) == 2.0 ** -18 == 3.814697265625e-06
    # the largest |coordinate| counts, a negative corner too: 300 m in [256, 512), steps of 2^-15 m
    assert ensemble.float32_floor([-300.0, 0.0, 0.0], [10.0, 5.0, 5.0]) == 2.0 ** -16
    # a 0.1 m box: 0.1 in [1/16, 1/8), steps of 2^-27 m
    assert ensemble.float32_floor([0.0, 0.0], [0.1, 0.05]) == 2.0 ** -28


def test_the_standard_deviation_is_the_radii_term_or_the_float32_floor_where_that_is_larger():
    box = ([0.0, 0.0], [100.0, 80.0])                       # floor 3.8147e-6 m
    std = ensemble.displacement_std(1e-5, np.array([1.0, 0.5, 0.2]), *box)
    np.testing.assert_array_equal(std, [1e-5, 5e-6, 2.0 ** -18])          # 0.2 m x 1e-5 = 2e-6 m is below it
    np.testing.assert_array_equal(ensemble.displacement_std(1e-3, np.array([0.2]), *box), [2e-4])


# ---- the draw ------------------------------------------------------------------------------------------------------


def _particles_setup(dim: int, n: int, kinematic: int, schedule: dem.RecordingSchedule,
                     spacing: float = 0.0) -> dem.Setup:
    """``n`` particles of radius RADIUS, the first ``kinematic`` of them fixed; 5 diameters apart in x with
    ``spacing`` = 0 (no contact), else on a square grid of that spacing above a fixed row."""
    kn = 1.0e5 if dim == 2 else 1.0e4
    c = dem.Contact(young=kn / RADIUS, kn=kn, kt_over_kn=0.2857, restitution=0.5, friction=0.5, rolling_friction=0.1)
    x = np.zeros((n, dim))
    if spacing:
        side = int(round((n - kinematic) ** (1.0 / dim)))
        grid = np.stack(np.meshgrid(*[np.arange(side)] * dim, indexing="ij"), -1).reshape(-1, dim) * spacing
        grid[:, -1] += 2.0 * RADIUS
        grid[:, 0] += 0.3 * RADIUS * np.sin(np.arange(len(grid)))        # off the grid: the pile falls apart
        x[kinematic:] = grid
        x[:kinematic, 0] = (np.arange(kinematic) - 1) * 2.0 * RADIUS
    else:
        x[:, 0] = np.arange(n) * 10.0 * RADIUS
    limit = contact.stable_time_step(contact.particle_mass(DENSITY, RADIUS, dim), kn)
    species = (np.arange(n) >= kinematic).astype(int)
    return dem.Setup(name="pile", particles=dem.Particles(x, np.full(n, RADIUS), species),
                     nominal_radius=RADIUS, kinematic_species=(0,), n_species=2, density=DENSITY, gravity=G,
                     contact=c, dt=0.02 * limit, dt_limit=limit, lower=np.full(dim, -1.0), upper=np.full(dim, 1.0),
                     max_overlap=1.0, schedule=schedule)


def _every(dim: int) -> int:
    """DEM steps of 0.01 s at 2 % of the stable step of the particles' contact."""
    kn = 1.0e5 if dim == 2 else 1.0e4
    return int(round(0.01 / (0.02 * contact.stable_time_step(contact.particle_mass(DENSITY, RADIUS, dim), kn))))


def _row(member: int, frame: int = 2, size: float = 1e-3, seed: int = 7) -> dict:
    return {ensemble.MEMBER: member, ensemble.FRAME: frame, ensemble.SIZE: size, "seed": seed}


@pytest.mark.parametrize("dim", [2, 3])
def test_the_draw_is_normal_with_the_rules_deviation_in_the_plane_and_spares_kinematic_particles(dim):
    setup = _particles_setup(dim, 4000, 1000, dem.RecordingSchedule(0, 10, 4))
    drawn = ensemble.draw(setup, 1e-3, seed=7, member=0)
    assert drawn.shape == (4000, dim)                                   # 2D: in-plane only
    np.testing.assert_array_equal(drawn[:1000], 0.0)                     # the fixed ones stay
    z = drawn[1000:] / 1e-5                                              # 1e-3 radii of 0.01 m (the box floor: 6e-8 m)
    assert abs(z.std() - 1.0) < 0.03 and abs(z.mean()) < 0.03            # N(0, 1) per axis over 3000 x D draws
    assert abs(np.mean(z**4) - 3.0) < 0.3                                # a normal's kurtosis, not a uniform's 1.8


def test_the_draw_is_seeded_by_the_sims_seed_and_the_member():
    setup = _particles_setup(2, 50, 5, dem.RecordingSchedule(0, 10, 4))
    a = ensemble.draw(setup, 1e-3, seed=7, member=1)
    np.testing.assert_array_equal(a, ensemble.draw(setup, 1e-3, seed=7, member=1))
    for other in (ensemble.draw(setup, 1e-3, seed=7, member=2), ensemble.draw(setup, 1e-3, seed=8, member=1)):
        assert not np.any(other[5:] == a[5:])


@pytest.mark.parametrize("change, match", [
    (dict(frame=3), "after frame 3; it must come after one of frames 0..2"),     # frame 3 is the last of 4
    (dict(displacement=np.ones((10, 3))), "of shape \\(10, 3\\) for particles of shape \\(10, 2\\)"),
    (dict(displacement=np.ones((10, 2))), "moves kinematic particles"),
])
def test_a_perturbation_no_engine_can_apply_is_refused_by_name(change, match):
    setup = _particles_setup(2, 10, 2, dem.RecordingSchedule(0, 10, 4))
    fields = {"frame": 1, "displacement": np.zeros((10, 2)), **change}
    with pytest.raises(dem.UnsupportedSetup, match=match):
        dem.checked_perturbation(dataclasses.replace(setup, perturbation=dem.Perturbation(**fields)))


# ---- real runs of both engines -------------------------------------------------------------------------------------


def _run(setup: dem.Setup, engine_name: str, row: dict | None, tmp_path) -> dem.Frames:
    if row is not None:
        setup = ensemble.member_setup(setup, row)
    folder = tmp_path / f"run{len(list(tmp_path.iterdir()))}"
    folder.mkdir()
    frames, _ = engine.driver(engine_name).run_recording(setup, folder)
    return frames


@pytest.mark.engine
@pytest.mark.parametrize("engine_name", ENGINES)
@pytest.mark.parametrize("dim", [2, 3])
def test_free_particles_keep_exactly_the_drawn_displacement_from_the_frame_on(engine_name, dim, tmp_path):
    """Free fall is the same motion from any start: a member's free particles are the sim's, shifted by their
    drawn displacement from frame K = 3 on (to the dump's digits), and the same before it; fixed ones never move."""
    setup = dataclasses.replace(_particles_setup(dim, 6, 2, dem.RecordingSchedule(0, _every(dim), 6)),
                                velocity=np.tile([0.3, 0.2, 0.1][:dim], (6, 1)) * (np.arange(6) >= 2)[:, None])
    sim, member = _run(setup, engine_name, None, tmp_path), _run(setup, engine_name, _row(1), tmp_path)
    drawn = ensemble.member_setup(setup, _row(1)).perturbation.displacement
    assert np.abs(drawn[2:]).min() > 1e-8                               # 1e-3 radii: about 1e-5 m per axis
    np.testing.assert_array_equal(member.position[:3], sim.position[:3])
    np.testing.assert_allclose(member.position[3:] - sim.position[3:], np.broadcast_to(drawn, (3, 6, dim)),
                               rtol=0, atol=1e-10)
    np.testing.assert_array_equal(member.kinetic_energy, sim.kinetic_energy)   # velocities are not displaced


@pytest.mark.engine
@pytest.mark.parametrize("engine_name", ENGINES)
@pytest.mark.parametrize("dim", [2, 3])
def test_a_member_replays_the_sim_to_its_frame_and_differs_after_it(engine_name, dim, tmp_path):
    """A pile collapsing onto a fixed row: each member's frames 0..K-1 (K = 4) are the sim's bit for bit, with the
    kinetic energy and the force on the fixed row at frame K-1 the unperturbed run's; every later frame differs;
    members 0 and 1 differ; member 1 run twice is the same run."""
    n_grid = 16 if dim == 2 else 27
    setup = _particles_setup(dim, 6 + n_grid, 6, dem.RecordingSchedule(0, _every(dim), 8), spacing=2.05 * RADIUS)
    sim = _run(setup, engine_name, None, tmp_path)
    runs = [_run(setup, engine_name, _row(j, frame=3, size=1e-5), tmp_path) for j in (0, 1, 1)]
    for member in runs:
        np.testing.assert_array_equal(member.step, sim.step)            # every frame once: none dumped twice
        np.testing.assert_array_equal(member.position[:4], sim.position[:4])
        np.testing.assert_array_equal(member.kinetic_energy[:4], sim.kinetic_energy[:4])
        np.testing.assert_array_equal(member.kinematic_force[:4], sim.kinematic_force[:4])
        assert np.all(np.abs(member.position[4:] - sim.position[4:]).max(axis=(1, 2)) > 0)
    assert np.all(np.abs(runs[0].position[4:] - runs[1].position[4:]).max(axis=(1, 2)) > 0)
    np.testing.assert_array_equal(runs[1].position, runs[2].position)
    np.testing.assert_array_equal(runs[1].kinetic_energy, runs[2].kinetic_energy)


@pytest.mark.engine
def test_a_members_h5md_file_records_the_member_and_starts_with_the_sims_stored_frames(tmp_path):
    """Through the simulate and convert stages (a ci slide sim in LAMMPS): the member's file holds its index, its
    frame K - 1, the size in radii and the deviations used, and its first K stored frames are the sim's."""
    cfg = config.load({"scale": "ci", "slide": {"n_sims": 3, "frames": 8, "record_start": 0.5,
                                                "settle_time": 4.0}})["slide"]
    engine.prepare(slide.SCENE, "lammps", slide.SCENE.packings(cfg)[0], tmp_path / "packing")
    row = sweep.build("slide", cfg).iloc[0].to_dict()
    row.pop("split")
    k = cfg["model"]["history"]
    member_row = {**row, **_row(1, frame=k - 1, size=cfg["evaluate"]["ensemble_perturbation"], seed=row["seed"])}
    trajectories = []
    for name, r in (("sim", row), ("member", member_row)):
        engine.simulate(slide.SCENE, r, tmp_path / "packing", tmp_path / name)
        trajectories.append(h5md.read(convert.convert(tmp_path / name, tmp_path / f"{name}.h5")))
    sim, member = trajectories
    p = member.parameters
    assert (p["ensemble_member"], p["perturb_frame"], p["perturbation"]) == (1, k - 1, 1e-5)
    assert p["perturbation_floor"] == 2.0 ** -18                        # the 100 m slide box
    assert p["perturbation_std_min"] == pytest.approx(1e-5 * member.radius[~member.kinematic].min(), rel=1e-12)
    assert p["perturbation_std_max"] == pytest.approx(1e-5 * member.radius[~member.kinematic].max(), rel=1e-12)
    np.testing.assert_array_equal(member.position[:k], sim.position[:k])
    assert np.abs(member.position[k:] - sim.position[k:]).max() > 1e-6
    assert "ensemble_member" not in sim.parameters
