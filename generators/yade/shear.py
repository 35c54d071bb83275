"""The direct-shear scene in YADE: settle a packing per modulus (prepare), shear it (simulate)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from generators import contact, stability
from generators.atomic import atomic_path
from generators.scenes import shear
from generators.yade import runner

PACKING_FILE = "packing.csv"
RUN_FILE = "run.json"
RAW_FILE = "frames.npz"


def _material(p: dict, dt: float) -> dict:
    # YADE's ViscElMat calls the tangential/normal stiffness ratio `poisson` (ks = kn * poisson)
    return {"young": p["young"], "poisson": p["kt_over_kn"], "restitution": p["restitution"],
            "density": p["density"], "friction": p["friction"], "gravity": p["gravity"], "dt": dt}


def _listening(run: runner.Run, where: str) -> None:
    """Refuse a run whose YADE process kept a listening socket (its TCP prompt or XML-RPC server)."""
    left = run.report.get("listening_at_start", []) + run.report.get("listening_sockets", [])
    if left:
        raise runner.YadeError(f"{where}: YADE held listening sockets {left} during the run")


def settle(params: dict, out_dir: Path) -> dict:
    """Pour the loose soil into the box (walls extended upwards), settle it, trim it at the box height."""
    loose = shear.loose_packing(params)
    dt, limit, _ = shear.dem_step(params, where=f"packing E = {params['young']:g} Pa")
    m_mean = contact.sphere_mass(params["density"], 0.5 * sum(params["radius"]))
    job = {"mode": "settle", **_material(params, dt), "position": loose.x.tolist(), "radius": loose.radius.tolist(),
           "fixed": (loose.species == shear.BOX).tolist(), "damping": params["settle_damping"],
           "check_every": 0.005, "settle_time": params["settle_time"],
           "energy_tol": 0.5 * m_mean * params["settle_speed"] ** 2}
    with atomic_path(out_dir) as tmp:
        tmp.mkdir()
        arrays, run = runner.run(job, tmp, "settle")
        _listening(run, f"packing {out_dir.name}")
        settled = shear.Particles(arrays["position"], loose.radius, loose.species, loose.lower)
        shear.check_filled(settled, params, f"packing {out_dir.name}")
        packing = shear.trim(settled, params)
        lower, upper = shear.domain(params, 0.0)
        stability.check_trajectory(f"packing {out_dir.name}", packing.x[None], packing.radius,
                                   packing.species == shear.BOX, lower, upper, params["max_overlap"])
        pd.DataFrame({"species": packing.species, "lower": packing.lower, "radius": packing.radius,
                      "x": packing.x[:, 0], "y": packing.x[:, 1], "z": packing.x[:, 2]}).to_csv(
            tmp / PACKING_FILE, index=False, float_format="%.10g")
        (tmp / "settle.npz").unlink()
        meta = {"params": params, "engine": "yade", "engine_version": run.version, "command": run.command,
                "wall_time": run.wall_time, "dt": dt, "dt_limit": limit, "settle_steps": int(arrays["iterations"]),
                "settle_time": float(arrays["time"]), "final_kinetic_per_sphere": float(arrays["kinetic_per_sphere"]),
                "n_soil": int((packing.species == shear.SOIL).sum()),
                "n_box": int((packing.species == shear.BOX).sum()),
                "servers_closed": run.report.get("servers_closed")}
        (tmp / RUN_FILE).write_text(json.dumps(meta, indent=2))
    return meta


def read_packing(packing_dir: Path) -> shear.Particles:
    t = pd.read_csv(Path(packing_dir) / PACKING_FILE)
    return shear.Particles(t[["x", "y", "z"]].to_numpy(float), t["radius"].to_numpy(float),
                           t["species"].to_numpy(int), t["lower"].to_numpy(bool))


def simulate(row: dict, packing_dir: Path, out_dir: Path) -> dict:
    """Shear the packing of the row's modulus by ``displacement`` over the recorded frames."""
    sim = row["id"]
    packing = read_packing(packing_dir)
    dt, limit, _ = shear.dem_step(row, where=sim)
    interval = row["displacement"] / (row["shear_speed"] * (row["frames"] - 1))
    every = max(1, int(round(interval / dt)))
    speed = row["displacement"] / (every * dt * (row["frames"] - 1))     # exact displacement at the last frame
    job = {"mode": "shear", **_material(row, dt), "position": packing.x.tolist(), "radius": packing.radius.tolist(),
           "fixed": (packing.species == shear.BOX).tolist(), "moving": packing.lower.tolist(),
           "velocity": [speed, 0.0, 0.0], "every": every, "frames": row["frames"]}
    with atomic_path(out_dir) as tmp:
        tmp.mkdir()
        try:
            arrays, run = runner.run(job, tmp, "shear")
        except runner.YadeError as exc:   # a failed run, not a numerical blow-up (check_trajectory names those)
            raise runner.YadeError(f"{sim}: {exc}") from exc
        _listening(run, sim)
        lower, upper = shear.domain(row, row["displacement"])
        kinematic = packing.species == shear.BOX
        stability.check_trajectory(sim, arrays["position"], packing.radius, kinematic, lower, upper,
                                   row["max_overlap"])
        np.savez_compressed(tmp / RAW_FILE, position=arrays["position"], step=arrays["step"], time=arrays["time"],
                            mass=arrays["mass"], radius=packing.radius, species=packing.species, lower=packing.lower)
        (tmp / "shear.npz").unlink()
        meta = {"params": row, "engine": "yade", "engine_version": run.version, "command": run.command,
                "wall_time": run.wall_time, "dt": dt, "dt_limit": limit, "steps_per_frame": every,
                "n_steps": every * (row["frames"] - 1), "window_seconds": float(arrays["loop_seconds"]),
                "window_steps": every * (row["frames"] - 1), "max_rss_mb": run.max_rss_mb,
                "frame_interval": every * dt, "shear_speed": speed, "packing": str(packing_dir),
                "servers_closed": run.report.get("servers_closed"),
                "listening_sockets": run.report.get("listening_sockets")}
        (tmp / RUN_FILE).write_text(json.dumps(meta, indent=2))
    return meta


def read_raw(raw_dir: Path) -> dict:
    with np.load(Path(raw_dir) / RAW_FILE) as data:
        raw = {k: data[k] for k in data.files}
    raw["kinematic"] = raw["species"] == shear.BOX
    return raw


def collision(young: float, radius: float, restitution: float, density: float, speed: float, workdir: Path,
              dt_safety: float = 0.02) -> tuple[float, runner.Run]:
    """Measured restitution of a head-on collision of two equal spheres in YADE."""
    kn = young * radius
    dt = dt_safety * contact.stable_time_step(contact.sphere_mass(density, radius), kn)
    job = {"mode": "collision", "young": young, "poisson": 0.3,   # ks / kn; no tangential load head-on
           "restitution": restitution, "density": density,
           "friction": 0.5, "gravity": 0.0, "dt": dt, "radius": [radius], "speed": speed}
    arrays, run = runner.run(job, Path(workdir), "collision")
    return float(arrays["after"] / arrays["before"]), run
