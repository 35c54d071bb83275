"""The meteorite scene in LAMMPS: settle the ground bed (prepare) and run one impact (simulate)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from generators import stability
from generators.atomic import atomic_path
from generators.lammps import energy, io, pair, runner
from generators.scenes import meteorite

PACKING_FILE = "packing.csv"
RUN_FILE = "run.json"
N_TYPES = 2


def _contact_variables(p: dict) -> dict[str, float]:
    dt, limit, kn = meteorite.dem_step(p, where=p.get("id", "meteorite"))
    return pair.granular_variables(p, dt, limit, kn)


def _bounds(p: dict) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros(2), np.asarray(p["domain"], float)


def settle(params: dict, out_dir: Path) -> dict:
    """Settle the loose ground bed of ``params`` under gravity; write packing.csv and run.json."""
    width, height = params["domain"]
    loose = meteorite.loose_bed(params, seed=[params["seed"], 2000 + params["packing_index"]])
    var = _contact_variables(params)
    chunk = max(1, int(round(0.5 / var["dt"])))                 # check every 0.5 s
    variables = {k: v for k, v in var.items() if not k.startswith("_")}
    variables.update(data="data.lammps", out=PACKING_FILE + ".dump", width=width,
                     gamma=params["settle_damping"] * var["_m_mean"], chunk=chunk,
                     max_chunks=max(1, int(math.ceil(params["settle_time"] / (chunk * var["dt"])))),
                     speed_tol=params["settle_speed"])
    with atomic_path(out_dir) as tmp:
        tmp.mkdir()
        io.write_data(tmp / "data.lammps", loose.x, loose.radius, loose.species + 1, (0.0, 0.0), (width, height),
                      n_types=N_TYPES, title="graphdem meteorite loose bed")
        run = runner.run("meteorite_settle.in", variables, tmp)
        (_, table), = io.read_dump(tmp / (PACKING_FILE + ".dump"))
        thermo = io.read_thermo(tmp / "log.lammps")
        packing = pd.DataFrame({"id": table["id"], "species": table["type"] - 1, "radius": table["radius"],
                                "x": table["x"], "y": table["y"]})
        lower, upper = _bounds(params)
        stability.check_trajectory(f"packing {out_dir.name}", packing[["x", "y"]].to_numpy()[None],
                                   packing["radius"].to_numpy(), np.zeros(len(packing), bool), lower, upper,
                                   params["max_overlap"])
        packing.to_csv(tmp / PACKING_FILE, index=False, float_format="%.10g")
        (tmp / (PACKING_FILE + ".dump")).unlink()
        meta = {
            "params": params, "engine": "lammps", "engine_version": run.version, "command": run.command,
            "wall_time": run.wall_time, "dt": var["dt"], "dt_limit": var["_dt_limit"],
            "settle_steps": int(thermo["Step"].iloc[-1]) if len(thermo) else 0,
            "final_rms_speed": float(thermo["v_rms_speed"].iloc[-1]) if len(thermo) else None,
            "n_ground": len(packing),
            "bed_top": float((packing["y"] + packing["radius"]).max()),
        }
        (tmp / RUN_FILE).write_text(json.dumps(meta, indent=2))
    return meta


def read_packing(packing_dir: Path) -> meteorite.Particles:
    table = pd.read_csv(Path(packing_dir) / PACKING_FILE)
    return meteorite.Particles(x=table[["x", "y"]].to_numpy(float), radius=table["radius"].to_numpy(float),
                               species=table["species"].to_numpy(int))


def simulate(row: dict, packing_dir: Path, out_dir: Path) -> dict:
    """Launch the meteorite of sweep row ``row`` at the settled bed and record the frames."""
    sim = row["id"]
    width, height = row["domain"]
    particles, velocity = meteorite.place_meteorite(row, read_packing(packing_dir))
    var = _contact_variables(row)
    every = max(1, int(round(row["frame_interval"] / var["dt"])))
    nsteps = every * (row["frames"] - 1)
    variables = {k: v for k, v in var.items() if not k.startswith("_")}
    variables.update(data="data.lammps", every=every, nsteps=nsteps, width=width,
                     vx=float(velocity[0]), vy=float(velocity[1]))
    with atomic_path(out_dir) as tmp:
        tmp.mkdir()
        io.write_data(tmp / "data.lammps", particles.x, particles.radius, particles.species + 1, (0.0, 0.0),
                      (width, height), n_types=N_TYPES, title=f"graphdem meteorite {sim}")
        try:
            run = runner.run("meteorite_simulate.in", variables, tmp)
        except runner.LammpsError as exc:
            raise stability.BlowUp(sim, exc.step // every, str(exc)) from exc
        raw = read_raw(tmp)
        lower, upper = _bounds(row)
        stability.check_trajectory(sim, raw["position"], raw["radius"], raw["kinematic"], lower, upper,
                                   row["max_overlap"])
        kinetic = energy.check_energy(sim, raw, io.read_thermo(tmp / "log.lammps"), row)
        (window_seconds, window_steps) = io.loop_times(tmp / "log.lammps")[-1]
        meta = {
            "params": row, "engine": "lammps", "engine_version": run.version, "command": run.command,
            "wall_time": run.wall_time, "dt": var["dt"], "dt_limit": var["_dt_limit"], "steps_per_frame": every,
            "n_steps": nsteps, "window_seconds": window_seconds, "window_steps": window_steps,
            "max_rss_mb": run.max_rss_mb, "frame_interval": every * var["dt"], "packing": str(packing_dir),
            "launch_velocity": velocity.tolist(), "kinetic_energy": kinetic.tolist(),
        }
        (tmp / RUN_FILE).write_text(json.dumps(meta, indent=2))
    return meta


def read_raw(raw_dir: Path) -> dict:
    """Positions and velocities [T, N, 2] of every particle, and the static fields."""
    raw_dir = Path(raw_dir)
    (_, static), = io.read_dump(raw_dir / "static.dump")
    frames = io.read_dump(raw_dir / "frames.dump")
    ids = static["id"].to_numpy()
    for step, table in frames:
        if not np.array_equal(table["id"].to_numpy(), ids):
            raise io.LammpsOutputError(f"{raw_dir}: frame at step {step} does not hold every particle once")
    return {"position": np.stack([t[["x", "y"]].to_numpy(float) for _, t in frames]),
            "velocity": np.stack([t[["vx", "vy"]].to_numpy(float) for _, t in frames]),
            "step": np.asarray([s for s, _ in frames]), "species": static["type"].to_numpy() - 1,
            "radius": static["radius"].to_numpy(float), "mass": static["mass"].to_numpy(float),
            "kinematic": np.zeros(len(ids), bool)}
