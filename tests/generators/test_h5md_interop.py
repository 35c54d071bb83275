"""Our H5MD files opened by another tool: MDAnalysis' H5MD reader (3D only), numbers compared frame by frame."""

import numpy as np
import pytest

from generators import h5md

mda = pytest.importorskip("MDAnalysis")
from MDAnalysis.coordinates.H5MD import H5MDReader  # noqa: E402

from generators import h5md_mdanalysis  # noqa: E402


def trajectory(d: int = 3, t: int = 7, n: int = 9) -> h5md.Trajectory:
    """A small random walk in a box whose lower corner is not the origin."""
    rng = np.random.default_rng(4)
    species = np.array([0, 0] + [1] * (n - 2))
    return h5md.Trajectory(
        position=(np.array([1.0, 2.0, 3.0][:d]) + np.cumsum(rng.normal(0, 0.01, (t, n, d)), axis=0)).astype(np.float32),
        time=0.5 + np.arange(t) * 2.5e-3, step=1000 + np.arange(t) * 250, species=species,
        radius=rng.uniform(0.01, 0.02, n), mass=np.where(species == 0, 0.0, rng.uniform(0.1, 0.2, n)),
        kinematic=species == 0, box_lower=np.array([-0.25, 0.5, 1.0][:d]), box_upper=np.array([2.0, 3.5, 4.75][:d]),
        boundary=("none",) * d, observables={"kinetic_energy": rng.uniform(0, 1, t)},
        observable_units={"kinetic_energy": "J"})


@pytest.fixture
def sim3d(tmp_path):
    traj = trajectory()
    return h5md.write(tmp_path / "sim.h5", traj), traj


def test_mdanalysis_reads_positions_box_and_times_of_every_frame(sim3d):
    path, traj = sim3d
    u = h5md_mdanalysis.universe(path)
    assert u.atoms.n_atoms == traj.n_particles and u.trajectory.n_frames == traj.n_frames
    assert u.trajectory.units["length"] == "m" and u.trajectory.units["time"] == "s"
    edges = traj.box_upper - traj.box_lower
    for i, ts in enumerate(u.trajectory):
        assert ts.frame == i
        np.testing.assert_array_equal(ts.positions, traj.position[i])           # float32 both, no unit scaling
        np.testing.assert_allclose(ts.dimensions, [*edges, 90.0, 90.0, 90.0], rtol=1e-7)
        assert ts.time == pytest.approx(traj.time[i], rel=1e-12)
        assert ts.data["step"] == traj.step[i]
        assert ts.data["kinetic_energy"] == pytest.approx(traj.observables["kinetic_energy"][i], rel=1e-12)
    np.testing.assert_array_equal(u.atoms.types, traj.species.astype(str))
    np.testing.assert_allclose(u.atoms.masses, traj.mass, rtol=1e-7)             # float32 in the file
    np.testing.assert_allclose(u.atoms.radii, traj.radius, rtol=1e-7)


def test_mdanalysis_alone_refuses_the_metre_with_or_without_unit_conversion(sim3d):
    """Pins MDAnalysis' behaviour documented in docs/data.md: its H5MD reader knows no SI length unit."""
    path, traj = sim3d
    for convert in (True, False):
        u = mda.Universe.empty(traj.n_particles)
        with pytest.raises(RuntimeError, match="length unit 'm' is not recognized"):
            u.load_new(str(path), format="H5MD", convert_units=convert)


def test_the_si_reader_leaves_mdanalysis_own_h5md_reader_registered():
    assert h5md_mdanalysis.si_reader() is h5md_mdanalysis.si_reader()
    assert mda._READERS["H5MD"] is H5MDReader and "m" not in H5MDReader._unit_translation["length"]


def test_mdanalysis_refuses_2d_files(tmp_path):
    path = h5md.write(tmp_path / "sim2d.h5", trajectory(d=2))
    with pytest.raises(ValueError, match="only supports 3-dimensional simulation boxes"):
        h5md_mdanalysis.universe(path)
