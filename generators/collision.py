"""Measure an engine's contact model with a head-on collision of two equal particles.

The collision is an ordinary Setup run by the engine's driver (no gravity, no walls): two particles
approach at +-``speed`` from a gap of a tenth of a radius; two frames recorded after they separate
give the rebound speed from their displacements. LAMMPS resolves a contact by ~16 steps at
dt_safety 0.1 and scatters the measured restitution by up to 10 %; at dt_safety 0.01 (~157 steps) it
is within 1 %. Tests measure it for each engine at each scene's own time step, for the scene's smallest pair
over several impact phases; `graphdem restitution` tabulates it for any step (docs/performance.md, "The
DEM's time step").
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from generators import contact, dem, engines


def collision_setup(c: dem.Contact, radius: float, density: float, dim: int, dt: float, speed: float) -> dem.Setup:
    mass = contact.particle_mass(density, radius, dim)
    contact_time = math.pi / math.sqrt(2.0 * c.kn / mass)
    steps = int((0.1 * radius / speed + 3.0 * contact_time) / dt)
    x = np.zeros((2, dim))
    x[:, 0] = (-1.05 * radius, 1.05 * radius)
    velocity = np.zeros((2, dim))
    velocity[:, 0] = (speed, -speed)
    every = max(1, -(-steps // 10))
    span = 10.0 * radius + 4.0 * speed * 11 * every * dt
    return dem.Setup(
        name="collision", particles=dem.Particles(x, np.full(2, radius), np.zeros(2, int)), nominal_radius=radius,
        kinematic_species=(), n_species=1, density=density, gravity=0.0, contact=c, dt=dt,
        dt_limit=contact.stable_time_step(mass, c.kn), lower=np.full(dim, -span), upper=np.full(dim, span),
        max_overlap=1.0, schedule=dem.RecordingSchedule(start=10 * every, every=every, frames=2), velocity=velocity)


def restitution(engine_name: str, c: dem.Contact, radius: float, density: float, dim: int, dt: float,
                speed: float, workdir: Path) -> float:
    """Rebound over impact speed of the collision, measured by ``engine_name``'s driver."""
    setup = collision_setup(c, radius, density, dim, dt, speed)
    frames, _ = engines.driver(engine_name).run_recording(setup, Path(workdir))
    x = np.asarray(frames.position, np.float64)[:, :, 0]
    elapsed = float(frames.time[1] - frames.time[0])
    rebound = ((x[1, 1] - x[1, 0]) - (x[0, 1] - x[0, 0])) / elapsed
    return rebound / (2.0 * speed)


def scene_pairs(setup: dem.Setup) -> dict[str, float]:
    """The sphere radii whose collisions a scene's time step must resolve: its smallest moving particle (the
    stable limit is that pair's) and its nominal one."""
    moving = ~np.isin(setup.particles.species, setup.kinematic_species)
    return {"smallest": float(setup.particles.radius[moving].min()), "nominal": float(setup.nominal_radius)}


def over_impact_phases(engine_name: str, setup: dem.Setup, radius: float, dt: float, phases: int,
                       workdir: Path) -> np.ndarray:
    """The restitution of two spheres of ``radius`` of ``setup``'s material at step ``dt``, measured at ``phases``
    approach speeds evenly from 1 to 1.3x the speed of a peak overlap of 1 % of a radius. Each speed starts
    the contact at another point of a time step, which moves the discrete contact's last step and with it the
    restitution: at ~50 steps per contact by up to about 2 %, not monotonically in ``dt``."""
    mass = contact.particle_mass(setup.density, radius, setup.dim)
    speed = 0.01 * radius * math.sqrt(2.0 * setup.contact.kn / mass)
    measured = []
    for i, factor in enumerate(np.linspace(1.0, 1.3, phases)):
        run = Path(workdir) / f"{engine_name}-{radius:.6g}-{dt:.6g}-{i}"
        run.mkdir(parents=True)
        measured.append(restitution(engine_name, setup.contact, radius, setup.density, setup.dim, dt,
                                    speed * factor, run))
    return np.asarray(measured)


def time_step_table(setup: dem.Setup, engine_names: list[str], dt_safeties: list[float], phases: int,
                    tolerance: float, workdir: Path) -> pd.DataFrame:
    """For each engine, pair (`scene_pairs`) and step (``dt_safeties`` x ``setup``'s stable limit): the largest and
    the median relative error of the restitution over ``phases`` impact phases, and whether the largest is
    within ``tolerance``. The cheapest step a scene can take is the largest whose every row passes."""
    rows = []
    for dt_safety in dt_safeties:
        for engine_name in engine_names:
            for pair, radius in scene_pairs(setup).items():
                e = over_impact_phases(engine_name, setup, radius, dt_safety * setup.dt_limit, phases, workdir)
                error = np.abs(e / setup.contact.restitution - 1.0)
                rows.append({"engine": engine_name, "pair": pair, "radius": radius, "dt_safety": dt_safety,
                             "dt": dt_safety * setup.dt_limit, "phases": phases, "max_error": float(error.max()),
                             "median_error": float(np.median(error)), "passes": bool(error.max() <= tolerance)})
    return pd.DataFrame(rows)
