"""Convert a simulate stage's raw folder (any scene, any engine) into one validated H5MD file
(docs/data.md): the engine's frames from its driver, everything else from the typed run record."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from generators import engines, h5md, record, scenes

# the engines' kinetic energy of the moving particles, translational and rotational (2D: discs of unit thickness)
ENERGY_UNIT = "J"


def trajectory(raw_dir: Path) -> h5md.Trajectory:
    raw_dir = Path(raw_dir)
    rec = record.read(raw_dir)
    if not isinstance(rec, record.SimRecord):
        raise record.RecordError(f"{raw_dir}: a {rec.kind} record, not a simulation's")
    scene = scenes.get(rec.scene)
    raw = engines.driver(rec.run.engine).read_raw(raw_dir, rec.dt)
    species = np.asarray(raw["species"])
    kinematic = np.isin(species, scene.kinematic_species)
    if "recorded" in raw and not np.all(raw["recorded"][~kinematic]):
        raise h5md.H5MDError(f"{raw_dir}: the engine did not record every moving particle "
                             f"({int((~raw['recorded'][~kinematic]).sum())} missing)")
    parameters = dict(rec.params)
    parameters.update(
        scene=scene.name, units="SI (m, s, kg, Pa)", engine=rec.run.engine, engine_version=rec.run.version,
        engine_command=rec.run.command, engine_wall_time=rec.run.wall_time, engine_ranks=rec.run.ranks,
        dem_time_step=rec.dt, dem_time_step_limit=rec.dt_limit, steps_per_frame=rec.steps_per_frame,
        frame_interval=rec.frame_interval,
        species_names={str(k): v for k, v in scene.species.items()}, contact_model=rec.contact_model,
        **rec.parameters)
    names = tuple(rec.properties)
    if rec.log_scaled_properties:
        parameters["log_scaled_properties"] = list(rec.log_scaled_properties)
    n = len(species)
    observables, units = {}, {}
    if rec.kinetic_energy is not None and len(rec.kinetic_energy) == len(raw["step"]):
        observables["kinetic_energy"], units["kinetic_energy"] = np.asarray(rec.kinetic_energy, float), ENERGY_UNIT
    for name, values in rec.observables.items():
        if len(values) != len(raw["step"]):
            raise h5md.H5MDError(f"{raw_dir}: observable {name!r} has {len(values)} values for {len(raw['step'])} "
                                 "frames")
        if name not in scene.observable_units:
            raise h5md.H5MDError(f"{raw_dir}: observable {name!r} has no unit: the {scene.name} scene declares units "
                                 f"for {sorted(scene.observable_units) or 'no observables'} (Scene.observable_units)")
        observables[name], units[name] = np.asarray(values, float), scene.observable_units[name]
    return h5md.Trajectory(
        position=np.asarray(raw["position"]).astype(np.float32), time=np.asarray(raw["time"]), step=raw["step"],
        species=species, radius=raw["radius"], mass=raw["mass"], kinematic=kinematic,
        box_lower=np.asarray(rec.box_lower), box_upper=np.asarray(rec.box_upper), boundary=("none",) * scene.dim,
        properties=np.tile(np.asarray([rec.properties[k] for k in names], np.float32), (n, 1)) if names else None,
        property_names=names, parameters=parameters, observables=observables, observable_units=units)


def convert(raw_dir: Path, out: Path) -> Path:
    return h5md.write(out, trajectory(raw_dir))
