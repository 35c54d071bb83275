"""The per-particle data MDAnalysis' topology is built from: what the H5MD file holds, particle for particle
(the Universe itself: tests/generators/test_h5md_interop.py)."""

import numpy as np

from generators import h5md, h5md_mdanalysis


def test_particle_data_is_the_file_s_species_mass_and_radius(tmp_path):
    n = 4
    species = np.array([0, 1, 1, 2])
    traj = h5md.Trajectory(position=np.zeros((2, n, 3)) + np.arange(n)[None, :, None], time=np.array([0.0, 0.1]),
                           step=np.array([0, 10]), species=species, radius=np.array([0.5, 0.25, 0.125, 0.0625]),
                           mass=np.array([0.0, 1.5, 2.5, 3.5]), kinematic=species == 0, box_lower=np.full(3, -1.0),
                           box_upper=np.full(3, 5.0))
    data = h5md_mdanalysis.particle_data(h5md.write(tmp_path / "sim.h5", traj))
    np.testing.assert_array_equal(data["species"], species)
    np.testing.assert_array_equal(data["mass"], traj.mass)         # values exact in float32
    np.testing.assert_array_equal(data["radius"], traj.radius)
