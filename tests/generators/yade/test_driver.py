"""The YADE job written from a Setup: what it maps, and what it refuses by name."""

import dataclasses

import numpy as np
import pytest

from generators import dem
from generators.yade import driver


def _setup(**extra) -> dem.Setup:
    x = np.array([[0.0, 0.0], [0.1, 0.0]])
    c = dem.Contact(young=1e9, kn=2e9, kt_over_kn=0.3, restitution=0.5, friction=0.7, rolling_friction=0.3)
    fields = dict(name="t", particles=dem.Particles(x, np.full(2, 1.0), np.array([0, 1])), nominal_radius=1.0,
                  kinematic_species=(0,), n_species=2, density=2650.0, gravity=9.81, contact=c, dt=1e-5,
                  dt_limit=1e-4, lower=np.full(2, -10.0), upper=np.full(2, 10.0), max_overlap=0.5,
                  schedule=dem.RecordingSchedule(start=0, every=10, frames=2),
                  walls=(dem.PlanarWall(axis=1, lower=0.0, upper=5.0),))
    fields.update(extra)
    return dem.Setup(**fields)


def test_2d_walls_and_a_weak_layer_map_to_the_job():
    weak = dataclasses.replace(_setup().contact, friction=0.05, rolling_friction=0.0)
    job = driver._job(_setup(species_contacts={1: weak}))
    assert job["dim"] == 2 and job["kn"] == 2e9 and job["fixed"] == [True, False]
    assert job["walls"] == [[1, 0.0, 1], [1, 5.0, -1]]          # the lower faces up, the upper down
    assert job["species_contacts"] == {"1": [0.05, 0.0]}


@pytest.mark.parametrize("change", [dict(friction=0.9), dict(restitution=0.2), dict(friction=0.1,
                                                                                       rolling_friction=0.1)])
def test_an_override_yade_cannot_combine_is_refused_by_name(change):
    override = dataclasses.replace(_setup().contact, **change)
    with pytest.raises(dem.UnsupportedSetup, match="per-species contact of species 1"):
        driver._job(_setup(species_contacts={1: override}))
