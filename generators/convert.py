"""Convert an engine's raw output folder into one validated H5MD file (docs/data.md)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from generators import h5md
from generators.lammps import slide as lammps_slide
from generators.scenes import slide


def slide_lammps(raw_dir: Path) -> h5md.Trajectory:
    raw_dir = Path(raw_dir)
    meta = json.loads((raw_dir / lammps_slide.RUN_FILE).read_text())
    row = meta["params"]
    raw = lammps_slide.read_raw(raw_dir)
    dt = meta["dt"]
    time = raw["step"] * dt
    parameters = {k: v for k, v in row.items()}
    parameters.update(
        scene="slide", units="SI (m, s, kg, Pa)", engine=meta["engine"],
        engine_version=meta["engine_version"], engine_command=meta["command"],
        engine_wall_time=meta["wall_time"], dem_time_step=dt, dem_time_step_limit=meta["dt_limit"],
        steps_per_frame=meta["steps_per_frame"], frame_interval=meta["frame_interval"],
        species_names={str(k): v for k, v in slide.SPECIES_NAMES.items()},
        contact_model=("linear spring-dashpot, Coulomb friction, rolling resistance "
                       "(LAMMPS granular hooke/tsuji/linear_history/sds)"),
    )
    observables = {}
    ke = np.asarray(meta.get("kinetic_energy", []), float)
    if len(ke) == len(time):
        observables["kinetic_energy"] = ke
    width, height = row["domain"]
    return h5md.Trajectory(
        position=raw["position"].astype(np.float32), time=time, step=raw["step"],
        species=raw["species"], radius=raw["radius"], mass=raw["mass"],
        kinematic=raw["kinematic"], box_lower=np.zeros(2), box_upper=np.array([width, height]),
        boundary=("none", "none"), parameters=parameters, observables=observables,
    )


CONVERTERS = {("slide", "lammps"): slide_lammps}


def convert(scene: str, raw_dir: Path, out: Path) -> Path:
    meta = json.loads((Path(raw_dir) / lammps_slide.RUN_FILE).read_text())
    engine = meta.get("engine")
    try:
        converter = CONVERTERS[(scene, engine)]
    except KeyError:
        raise ValueError(f"no converter for scene {scene!r} run by engine {engine!r}; "
                         f"known: {sorted(CONVERTERS)}") from None
    return h5md.write(out, converter(raw_dir))
