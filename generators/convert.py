"""Convert an engine's raw output folder into one validated H5MD file (docs/data.md)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from generators import h5md
from generators.lammps import meteorite as lammps_meteorite
from generators.lammps import slide as lammps_slide
from generators.scenes import meteorite, shear, slide
from generators.yade import shear as yade_shear

RUN_FILE = "run.json"      # every driver's raw folder holds its run.json


LAMMPS_CONTACT = ("linear spring-dashpot, Coulomb friction, rolling resistance "
                  "(LAMMPS granular hooke/tsuji/linear_history/sds)")


def _parameters(scene: str, meta: dict, names: dict[int, str], contact_model: str) -> dict:
    """The H5MD /parameters of a run: its sweep row plus the engine's provenance."""
    parameters = dict(meta["params"])
    parameters.update(
        scene=scene, units="SI (m, s, kg, Pa)", engine=meta["engine"], engine_version=meta["engine_version"],
        engine_command=meta["command"], engine_wall_time=meta["wall_time"], dem_time_step=meta["dt"],
        dem_time_step_limit=meta["dt_limit"], steps_per_frame=meta["steps_per_frame"],
        frame_interval=meta["frame_interval"], species_names={str(k): v for k, v in names.items()},
        contact_model=contact_model)
    return parameters


def slide_lammps(raw_dir: Path) -> h5md.Trajectory:
    raw_dir = Path(raw_dir)
    meta = json.loads((raw_dir / lammps_slide.RUN_FILE).read_text())
    row = meta["params"]
    raw = lammps_slide.read_raw(raw_dir)
    dt = meta["dt"]
    time = raw["step"] * dt
    parameters = _parameters("slide", meta, slide.SPECIES_NAMES, LAMMPS_CONTACT)
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


def meteorite_lammps(raw_dir: Path) -> h5md.Trajectory:
    raw_dir = Path(raw_dir)
    meta = json.loads((raw_dir / RUN_FILE).read_text())
    raw = lammps_meteorite.read_raw(raw_dir)
    parameters = _parameters("meteorite", meta, meteorite.SPECIES_NAMES,
                             LAMMPS_CONTACT + "; planar side and bottom walls")
    parameters["launch_velocity"] = meta["launch_velocity"]
    width, height = meta["params"]["domain"]
    return h5md.Trajectory(
        position=raw["position"].astype(np.float32), time=raw["step"] * meta["dt"], step=raw["step"],
        species=raw["species"], radius=raw["radius"], mass=raw["mass"], kinematic=raw["kinematic"],
        box_lower=np.zeros(2), box_upper=np.array([width, height]), boundary=("none", "none"),
        parameters=parameters, observables={"kinetic_energy": np.asarray(meta["kinetic_energy"], float)})


def shear_yade(raw_dir: Path) -> h5md.Trajectory:
    raw_dir = Path(raw_dir)
    meta = json.loads((raw_dir / RUN_FILE).read_text())
    row = meta["params"]
    raw = yade_shear.read_raw(raw_dir)
    parameters = _parameters("shear", meta, shear.SPECIES_NAMES,
                             "linear spring-dashpot, Coulomb friction (YADE ViscElMat, Law2_ScGeom_ViscElPhys_Basic)")
    parameters.update(split_height=shear.split_height(row), shear_speed=meta["shear_speed"],
                      log_scaled_properties=["young"])
    lower, upper = shear.domain(row, row["domain_displacement"])
    n = len(raw["radius"])
    return h5md.Trajectory(
        position=raw["position"].astype(np.float32), time=raw["time"], step=raw["step"], species=raw["species"],
        radius=raw["radius"], mass=raw["mass"], kinematic=raw["kinematic"], box_lower=lower, box_upper=upper,
        boundary=("none", "none", "none"), properties=np.full((n, 1), row["young"], np.float32),
        property_names=("young",), parameters=parameters)


CONVERTERS = {("slide", "lammps"): slide_lammps, ("meteorite", "lammps"): meteorite_lammps,
              ("shear", "yade"): shear_yade}


def convert(scene: str, raw_dir: Path, out: Path) -> Path:
    meta = json.loads((Path(raw_dir) / RUN_FILE).read_text())
    engine = meta.get("engine")
    try:
        converter = CONVERTERS[(scene, engine)]
    except KeyError:
        raise ValueError(f"no converter for scene {scene!r} run by engine {engine!r}; "
                         f"known: {sorted(CONVERTERS)}") from None
    return h5md.write(out, converter(raw_dir))
