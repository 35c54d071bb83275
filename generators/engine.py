"""Run a scene in an engine: the prepare and simulate stages for every scene and every engine.

The scene describes (generators/scene.py), the engine's driver runs (generators/<engine>/driver.py, found
through the registry generators/engines.py), and this module does what every run shares: atomic output
folders, the settled packing's table, the blow-up checks (non-finite values, escapes, overlaps, energy gain;
generators/blowup.py) and the typed run record (generators/record.py).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from generators import blowup, dem, ensemble, record
from generators.atomic import atomic_path
from generators.engines import driver
from generators.scene import Scene

PACKING_FILE = "packing.csv"
AXES = "xyz"


def write_packing(path: Path, particles: dem.Particles) -> None:
    table = {"species": particles.species, **{k: v for k, v in particles.groups.items()}, "radius": particles.radius}
    table.update({AXES[a]: particles.x[:, a] for a in range(particles.dim)})
    pd.DataFrame(table).to_csv(path, index=False, float_format="%.10g")


def read_packing(packing_dir: Path) -> dem.Particles:
    table = pd.read_csv(Path(packing_dir) / PACKING_FILE)
    axes = [a for a in AXES if a in table.columns]
    groups = [c for c in table.columns if c not in ("species", "radius", *axes)]
    return dem.Particles(table[axes].to_numpy(float), table["radius"].to_numpy(float), table["species"].to_numpy(int),
                         {g: table[g].to_numpy(bool) for g in groups})


def prepare(scene: Scene, engine: str, params: dict, out_dir: Path, ranks: int = 1) -> record.PackingRecord:
    """Settle the loose packing of ``params`` in ``engine`` (LAMMPS: on ``ranks`` MPI ranks); write packing.csv
    and run.json to ``out_dir``."""
    out_dir = Path(out_dir)
    setup = scene.settle_setup(params)
    with atomic_path(out_dir) as tmp:
        tmp.mkdir()
        settled, run = driver(engine).settle(setup, tmp, ranks=ranks)
        where = f"packing {out_dir.name}"
        packing = scene.settled(params, settled, where)
        kinematic = np.isin(packing.species, setup.kinematic_species)
        blowup.check_trajectory(where, packing.x[None], packing.radius, kinematic, np.asarray(setup.lower),
                                np.asarray(setup.upper), setup.max_overlap)
        write_packing(tmp / PACKING_FILE, packing)
        rec = record.PackingRecord(scene=scene.name, params=params, run=run, dt=setup.dt, dt_limit=setup.dt_limit,
                                   settle_steps=run.steps, n_moving=int((~kinematic).sum()),
                                   n_kinematic=int(kinematic.sum()))
        record.write(tmp / record.RUN_FILE, rec)
    return rec


def perturbed(packing: dem.Particles, kinematic_species: tuple[int, ...], scale: float, seed: int) -> dem.Particles:
    """The packing with every moving particle displaced by a normal draw of ``scale`` radii per axis
    (the DEM's own chaos: the same sim rerun from a slightly different state)."""
    moving = ~np.isin(packing.species, kinematic_species)
    rng = np.random.default_rng([int(seed), 0x5EED])
    x = packing.x.copy()
    x[moving] += rng.normal(0.0, 1.0, x[moving].shape) * (scale * packing.radius[moving])[:, None]
    return dem.Particles(x, packing.radius, packing.species, packing.groups)


def simulate(scene: Scene, row: dict, packing_dir: Path, out_dir: Path, ranks: int = 1,
             threads: int = 1) -> record.SimRecord:
    """Run sweep row ``row`` from its settled packing in the row's engine (LAMMPS: on ``ranks`` MPI ranks; YADE:
    on ``threads`` threads); raw output, the engine's own input and log, and run.json in ``out_dir``. A blow-up
    raises BlowUp naming the sim, frame and cause. A DEM ensemble member's row (``perturb_frame``,
    generators/ensemble.py) runs from the packing as it is and is perturbed after that frame; any other row
    with ``perturbation`` > 0 starts from the packing perturbed by that many radii (:func:`perturbed`)."""
    out_dir = Path(out_dir)
    packing = read_packing(packing_dir)
    member = ensemble.is_member(row)
    if row.get("perturbation") and not member:
        packing = perturbed(packing, scene.kinematic_species, float(row["perturbation"]), row["seed"])
    setup = scene.simulate_setup(row, packing)
    if member:
        setup = ensemble.member_setup(setup, row)
    runner = driver(row["engine"])
    schedule = setup.schedule
    with atomic_path(out_dir) as tmp:
        tmp.mkdir()
        frames, run = runner.run_recording(setup, tmp, ranks=ranks, threads=threads)
        blowup.check_trajectory(setup.name, frames.position, frames.radius, setup.kinematic,
                                np.asarray(setup.lower), np.asarray(setup.upper), setup.max_overlap)
        if setup.max_energy_gain is not None:
            if frames.kinetic_energy is None:
                raise dem.UnsupportedSetup(f"{setup.name}: the {row['engine']} driver reports no kinetic energy, "
                                           "which the energy check of this scene needs")
            blowup.check_energy_of(setup, frames.position, frames.mass, frames.radius, frames.kinetic_energy)
        box_lower, box_upper = setup.box
        rec = record.SimRecord(
            scene=scene.name, params=row, run=run, dt=setup.dt, dt_limit=setup.dt_limit,
            steps_per_frame=schedule.every, record_start_step=schedule.start,
            n_steps=schedule.start + schedule.every * (schedule.frames - 1),
            window_steps=schedule.every * (schedule.frames - 1), frame_interval=schedule.every * setup.dt,
            packing=str(packing_dir), box_lower=[float(v) for v in box_lower],
            box_upper=[float(v) for v in box_upper], contact_model=runner.CONTACT_MODEL + _walls(setup),
            parameters={**scene.h5md_parameters(row, setup), **(ensemble.parameters(setup, row) if member else {})},
            properties=scene.properties(row),
            log_scaled_properties=list(scene.log_scaled_properties),
            kinetic_energy=None if frames.kinetic_energy is None else [float(e) for e in frames.kinetic_energy],
            observables={k: [float(v) for v in np.asarray(values, float)]
                         for k, values in scene.observables(row, setup, frames).items()})
        record.write(tmp / record.RUN_FILE, rec)
    return rec


def _walls(setup: dem.Setup) -> str:
    if not setup.walls:
        return ""
    names = [f"{'xyz'[w.axis]} = {', '.join(f'{b:g}' for b in (w.lower, w.upper) if b is not None)} m"
             for w in setup.walls]
    return "; planar walls at " + "; ".join(names)
