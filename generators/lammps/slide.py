"""The slide scene in LAMMPS: settle a packing (prepare) and run one triggered slide (simulate)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from generators import stability
from generators.atomic import atomic_path
from generators.lammps import energy, io, pair, runner
from generators.scenes import slide

PACKING_FILE = "packing.csv"
RUN_FILE = "run.json"


def _contact_variables(p: dict) -> dict[str, float]:
    """LAMMPS pair parameters of the scene's linear spring-dashpot contact."""
    dt, limit, kn = slide.dem_step(p, where=p.get("id", "slide"))
    return pair.granular_variables(p, dt, limit, kn)


def _lammps_types(species: np.ndarray) -> np.ndarray:
    return np.asarray(species) + 1   # LAMMPS types start at 1


def settle(params: dict, out_dir: Path) -> dict:
    """Settle the loose packing of ``params`` under gravity; write packing.csv and run.json."""
    width, height = params["domain"]
    loose = slide.loose_packing(params, seed=[params["seed"], 1000 + params["packing_index"]])
    var = _contact_variables(params)
    chunk = max(1, int(round(0.5 / var["dt"])))                 # check every 0.5 s
    variables = {k: v for k, v in var.items() if not k.startswith("_")}
    variables.update(
        data="data.lammps", out=PACKING_FILE + ".dump",
        gamma=params["settle_damping"] * var["_m_mean"], chunk=chunk,
        max_chunks=max(1, int(math.ceil(params["settle_time"] / (chunk * var["dt"])))),
        speed_tol=params["settle_speed"])
    with atomic_path(out_dir) as tmp:
        tmp.mkdir()
        io.write_data(tmp / "data.lammps", loose.x, loose.radius, _lammps_types(loose.species),
                      (0.0, 0.0), (width, height), n_types=3, title="graphdem slide loose packing")
        run = runner.run("slide_settle.in", variables, tmp)
        (_, table), = io.read_dump(tmp / (PACKING_FILE + ".dump"))
        thermo = io.read_thermo(tmp / "log.lammps")
        packing = pd.DataFrame({"id": table["id"], "species": table["type"] - 1,
                                "radius": table["radius"], "x": table["x"], "y": table["y"]})
        stability.check_trajectory(
            f"packing {out_dir.name}", packing[["x", "y"]].to_numpy()[None],
            packing["radius"].to_numpy(), packing["species"].to_numpy() == slide.BEDROCK,
            np.zeros(2), np.array([width, height]), params["max_overlap"])
        packing.to_csv(tmp / PACKING_FILE, index=False, float_format="%.10g")
        (tmp / (PACKING_FILE + ".dump")).unlink()
        meta = {
            "params": params, "engine": "lammps", "engine_version": run.version,
            "command": run.command, "wall_time": run.wall_time, "dt": var["dt"],
            "dt_limit": var["_dt_limit"],
            "settle_steps": int(thermo["Step"].iloc[-1]) if len(thermo) else 0,
            "final_rms_speed": float(thermo["v_rms_speed"].iloc[-1]) if len(thermo) else None,
            "n_soil": int((packing["species"] != slide.BEDROCK).sum()),
            "n_bedrock": int((packing["species"] == slide.BEDROCK).sum()),
        }
        (tmp / RUN_FILE).write_text(json.dumps(meta, indent=2))
    return meta


def read_packing(packing_dir: Path) -> slide.Particles:
    table = pd.read_csv(Path(packing_dir) / PACKING_FILE)
    return slide.Particles(x=table[["x", "y"]].to_numpy(float), radius=table["radius"].to_numpy(float),
                           species=table["species"].to_numpy(int))


def simulate(row: dict, packing_dir: Path, out_dir: Path) -> dict:
    """Trigger the weak layer on a settled packing and record the frames; raw output in out_dir."""
    sim = row["id"]
    width, height = row["domain"]
    packing = read_packing(packing_dir)
    species = slide.assign_layers(packing, row["weak_base"], row["weak_thickness"], row["weak_dip"])
    var = _contact_variables(row)
    every = max(1, int(round(row["frame_interval"] / var["dt"])))
    nstart = every * int(round(row["record_start"] / (every * var["dt"])))
    nsteps = every * (row["frames"] - 1)
    variables = {k: v for k, v in var.items() if not k.startswith("_")}
    variables.update(data="data.lammps", every=every, nstart=nstart, nsteps=nsteps,
                     weak_mu=row["weak_friction"], weak_mur=row["weak_rolling_friction"])
    with atomic_path(out_dir) as tmp:
        tmp.mkdir()
        io.write_data(tmp / "data.lammps", packing.x, packing.radius, _lammps_types(species),
                      (0.0, 0.0), (width, height), n_types=3, title=f"graphdem slide {sim}")
        try:
            run = runner.run("slide_simulate.in", variables, tmp)
        except runner.LammpsError as exc:
            cause = str(exc)
            if "Lost atoms" in cause:
                cause = f"particles left the domain ({cause})"
            elif "Non-numeric" in cause or "nan" in cause.lower():
                cause = f"non-finite values ({cause})"
            if exc.step < nstart:
                cause += (f", after DEM step {exc.step} (its last thermo output), in the run-up before the first "
                          f"recorded frame")
            raise stability.BlowUp(sim, max(0, exc.step - nstart) // every, cause) from exc
        raw = read_raw(tmp)
        stability.check_trajectory(sim, raw["position"], raw["radius"], raw["kinematic"],
                                   np.zeros(2), np.array([width, height]), row["max_overlap"])
        thermo = io.read_thermo(tmp / "log.lammps")
        energy.check_energy(sim, raw, thermo, row)
        (window_seconds, window_steps) = io.loop_times(tmp / "log.lammps")[-1]
        meta = {
            "params": row, "engine": "lammps", "engine_version": run.version,
            "command": run.command, "wall_time": run.wall_time, "dt": var["dt"],
            "dt_limit": var["_dt_limit"], "steps_per_frame": every, "n_steps": nstart + nsteps,
            "record_start_step": nstart,
            "window_seconds": window_seconds, "window_steps": window_steps,   # the recorded window's loop time
            "max_rss_mb": run.max_rss_mb,
            "frame_interval": every * var["dt"], "packing": str(packing_dir),
            "kinetic_energy": (thermo["c_ke"] + thermo["c_erot"]).tolist() if len(thermo) else [],
        }
        (tmp / RUN_FILE).write_text(json.dumps(meta, indent=2))
    return meta


def read_raw(raw_dir: Path) -> dict:
    """Positions [T, N, 2] of every particle (bedrock from the static dump) and the static fields."""
    raw_dir = Path(raw_dir)
    (_, static), = io.read_dump(raw_dir / "static.dump")
    frames = io.read_dump(raw_dir / "frames.dump")
    data = _read_data_positions(raw_dir / "data.lammps")
    ids = static["id"].to_numpy()
    index = {int(i): k for k, i in enumerate(ids)}
    species = static["type"].to_numpy() - 1
    kinematic = species == slide.BEDROCK
    position = np.repeat(data[None, ids - 1], len(frames), axis=0)
    steps = []
    for f, (step, table) in enumerate(frames):
        rows = [index[int(i)] for i in table["id"]]
        position[f, rows] = table[["x", "y"]].to_numpy(float)
        steps.append(step)
    moving_ids = set(frames[0][1]["id"].astype(int))
    if moving_ids != {int(i) for i, k in zip(ids, kinematic, strict=True) if not k}:
        raise io.LammpsOutputError(f"{raw_dir}: dumped particles are not exactly the moving ones")
    return {"position": position, "step": np.asarray(steps), "species": species,
            "radius": static["radius"].to_numpy(float), "mass": static["mass"].to_numpy(float),
            "kinematic": kinematic}


def _read_data_positions(path: Path) -> np.ndarray:
    lines = Path(path).read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("Atoms")) + 2
    table = np.array([line.split() for line in lines[start:] if line.strip()], float)
    order = np.argsort(table[:, 0])
    return table[order][:, 4:6]
