"""Pictures of particle configurations: the plane section of 3D spheres (circle radii from the cut's height) and
the first/last picture, whose discs are drawn to scale and whose missed spheres are left out."""

import numpy as np

from generators import plots


def test_a_plane_cuts_each_sphere_in_a_circle_of_radius_sqrt_r2_minus_dz2():
    # unit spheres with centres 0, 0.6, 1 and 2 above the plane z = 0.5: circles of radius 1 and
    # sqrt(1 - 0.36) = 0.8; the sphere that only touches the plane, and the one above it, are missed
    position = np.array([[[1.0, 2.0, 0.5], [3.0, 4.0, 1.1], [5.0, 6.0, 1.5], [7.0, 8.0, 2.5]]])
    xy, radius = plots.plane_section(position, np.ones(4), 0.5)
    np.testing.assert_allclose(radius[0], [1.0, 0.8, 0.0, 0.0])
    np.testing.assert_array_equal(xy[0, :2], [[1.0, 2.0], [3.0, 4.0]])
    assert np.isnan(xy[0, 2:]).all()
    # along another axis: the cut of y = 2 keeps x and z
    xy, radius = plots.plane_section(position, np.full(4, 0.5), 2.0, axis=1)
    np.testing.assert_allclose(radius[0], [0.5, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(xy[0, 0], [1.0, 0.5])


def test_first_last_draws_the_discs_of_both_frames_to_scale(tmp_path, monkeypatch):
    drawn = []
    real = plots.draw_discs

    def spy(ax, xy, radius, species, alpha=1.0):
        drawn.append((np.asarray(xy), np.asarray(radius), np.asarray(species)))
        real(ax, xy, radius, species, alpha)
        np.testing.assert_array_equal(ax.collections[-1].get_offsets(), xy)     # discs centred where given

    monkeypatch.setattr(plots, "draw_discs", spy)
    position = np.array([[[1.0, 1.0], [2.0, 1.0], [np.nan, np.nan]], [[1.0, 2.0], [2.0, 2.5], [3.0, 3.0]]])
    radius = np.array([[0.5, 0.25, 0.1], [0.5, 0.25, 0.1]])          # [T, N]: a plane section's circles
    path = plots.first_last(tmp_path / "pic.png", position, radius, np.array([0, 1, 2]), np.array([0.0, 0.5]),
                            np.zeros(2), np.full(2, 4.0), "t", labels={0: "wall", 1: "grain"})
    assert path.read_bytes()[:4] == b"\x89PNG"
    (xy0, r0, s0), (xy1, r1, s1) = drawn
    np.testing.assert_array_equal(xy0, position[0, :2])              # the missed third sphere is left out
    np.testing.assert_array_equal(r0, [0.5, 0.25])
    np.testing.assert_array_equal(s0, [0, 1])
    np.testing.assert_array_equal(xy1, position[1])
    np.testing.assert_array_equal(r1, radius[1])
