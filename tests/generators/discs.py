"""A few 2D discs of unit thickness whose motion is known in closed form, as a Setup any engine driver runs: the
engine tests of the LAMMPS driver and of the YADE script share them."""

from __future__ import annotations

import numpy as np

from generators import dem

G, DT, KN, DENSITY, R_NOMINAL = 9.81, 1e-4, 1e5, 2650.0, 0.01

# a fixed disc (species 0) and two free discs far from it and from each other, the second thrown sideways
X0 = np.array([[0.0, 0.0], [0.1, 0.05], [0.2, 0.08]])
RADIUS = np.array([0.01, 0.01, 0.015])
V0 = np.array([[0.0, 0.0], [0.0, 0.0], [0.3, 0.0]])


def disc_mass(r):
    return DENSITY * np.pi * np.asarray(r) ** 2          # a 2D disc of unit thickness


def setup(x, radius, species, schedule, **extra) -> dem.Setup:
    """Discs at ``x`` in a domain [-1, 1]^2, species 0 kinematic, contact kn = KN; ``extra``: other Setup fields."""
    contact = dem.Contact(young=1e7, kn=KN, kt_over_kn=0.3, restitution=0.5, friction=0.4)
    fields = dict(name="tiny", particles=dem.Particles(np.asarray(x, float), np.asarray(radius, float),
                                                       np.asarray(species)),
                  nominal_radius=R_NOMINAL, kinematic_species=(0,), n_species=2, density=DENSITY, gravity=G,
                  contact=contact, dt=DT, dt_limit=1e-3, lower=np.full(2, -1.0), upper=np.full(2, 1.0),
                  max_overlap=0.5, schedule=schedule)
    fields.update(extra)
    return dem.Setup(**fields)


def settling_on_a_wall(radius) -> dem.Setup:
    """Discs of ``radius`` dropped from just above a wall at y = 0, far apart, settled by a viscous damping until
    their RMS speed is below 1e-5 m/s."""
    radius = np.asarray(radius, float)
    x = np.stack([0.3 * np.arange(len(radius)), radius + 0.002], axis=1)
    schedule = dem.Settle(damping=20.0, damping_kind="viscous", check_every=0.01, max_time=2.0, speed=1e-5)
    return setup(x, radius, np.zeros(len(radius), int), schedule, kinematic_species=(), n_species=1,
                 walls=(dem.PlanarWall(axis=1, lower=0.0, upper=None),))
