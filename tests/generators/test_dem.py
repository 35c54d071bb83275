"""The engine-neutral DEM description: particle sets keep their named groups aligned with the particles through
subset and concat, a Setup's box, groups and kinematic mask, and the perturbations every driver refuses."""

import numpy as np
import pytest

from generators import dem


def _particles() -> dem.Particles:
    """Four discs, particle k at x = k, radius 0.1 (k + 1), species k % 2; group "odd" marks particles 1 and 3."""
    k = np.arange(4)
    return dem.Particles(np.stack([k, np.zeros(4)], axis=1).astype(float), 0.1 * (k + 1), k % 2,
                         {"odd": k % 2 == 1})


def test_subset_keeps_every_field_and_group_on_its_particle():
    p = _particles()
    for keep in (np.array([True, False, True, True]), np.array([3, 0, 1])):     # a mask, and a reordering
        s = p.subset(keep)
        # particle k is identified by its x = k: every other field must be particle k's
        k = s.x[:, 0].astype(int)
        np.testing.assert_array_equal(s.radius, 0.1 * (k + 1))
        np.testing.assert_array_equal(s.species, k % 2)
        np.testing.assert_array_equal(s.groups["odd"], k % 2 == 1)
    assert p.subset(np.zeros(4, bool)).x.shape == (0, 2)


def test_concat_appends_and_fills_a_group_one_side_lacks_with_false():
    a = _particles()
    b = dem.Particles(np.array([[10.0, 1.0]]), np.array([0.5]), np.array([2]), {"lid": np.array([True])})
    c = a.concat(b)
    np.testing.assert_array_equal(c.x, np.vstack([a.x, b.x]))
    np.testing.assert_array_equal(c.radius, np.r_[a.radius, 0.5])
    np.testing.assert_array_equal(c.species, [0, 1, 0, 1, 2])
    assert list(c.groups) == ["lid", "odd"]                              # the union, in name order
    np.testing.assert_array_equal(c.groups["odd"], [False, True, False, True, False])
    np.testing.assert_array_equal(c.groups["lid"], [False, False, False, False, True])
    # a subset of the concatenation is the concatenation of the subsets
    back = c.subset(np.arange(4))
    np.testing.assert_array_equal(back.groups["odd"], a.groups["odd"])
    assert not back.groups["lid"].any()
    assert c.dim == 2


def _setup(**extra) -> dem.Setup:
    contact = dem.Contact(young=1e7, kn=1e5, kt_over_kn=0.3, restitution=0.5, friction=0.4)
    fields = dict(name="t", particles=_particles(), nominal_radius=0.25, kinematic_species=(0,), n_species=2,
                  density=2650.0, gravity=9.81, contact=contact, dt=1e-5, dt_limit=1e-4, lower=np.full(2, -1.0),
                  upper=np.full(2, 5.0), max_overlap=0.5, schedule=dem.RecordingSchedule(start=0, every=10, frames=4))
    fields.update(extra)
    return dem.Setup(**fields)


def test_setup_box_group_and_kinematic_mask():
    s = _setup()
    lower, upper = s.box
    np.testing.assert_array_equal(lower, s.lower)                        # no data box: the domain
    np.testing.assert_array_equal(upper, s.upper)
    lower, upper = _setup(box_lower=np.zeros(2), box_upper=np.full(2, 3.0)).box
    np.testing.assert_array_equal(lower, [0.0, 0.0])
    np.testing.assert_array_equal(upper, [3.0, 3.0])
    np.testing.assert_array_equal(s.kinematic, [True, False, True, False])   # species 0 is kinematic
    np.testing.assert_array_equal(s.group("odd"), [False, True, False, True])
    with pytest.raises(ValueError, match=r"t: no particle group 'lid'; groups: \['odd'\]"):
        s.group("lid")
    assert s.dim == 2


def _perturbation(frame: int, rows=(1, 3)) -> dem.Perturbation:
    d = np.zeros((4, 2))
    d[list(rows)] = 1e-3
    return dem.Perturbation(frame=frame, displacement=d)


def test_a_perturbation_after_any_frame_but_the_last_is_accepted():
    # 4 frames: frames 0, 1 and 2 are each followed by another
    for frame in (0, 1, 2):
        p = _perturbation(frame)
        assert dem.checked_perturbation(_setup(perturbation=p)) is p
    assert dem.checked_perturbation(_setup()) is None


@pytest.mark.parametrize("setup, message", [
    (dict(perturbation=_perturbation(3)), r"after frame 3; it must come after one of frames 0\.\.2 of a recorded run "
                                          "of 4 frames"),
    (dict(perturbation=_perturbation(-1)), "after frame -1"),
    (dict(perturbation=_perturbation(0),
          schedule=dem.Settle(damping=1.0, damping_kind="viscous", check_every=0.1, max_time=1.0, speed=1e-3)),
     "recorded run of 0 frames"),
    (dict(perturbation=dem.Perturbation(0, np.zeros((3, 2)))), r"shape \(3, 2\) for particles of shape \(4, 2\)"),
    (dict(perturbation=_perturbation(0, rows=(0,))), "moves kinematic particles"),
])
def test_a_perturbation_no_engine_can_apply_is_refused_by_name(setup, message):
    with pytest.raises(dem.UnsupportedSetup, match=message):
        dem.checked_perturbation(_setup(**setup))
