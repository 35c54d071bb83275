"""The YADE driver: runs any scene's Setup (generators/dem.py) that YADE supports.

Debian's ``yade -n -x`` runs generators/yade/scripts/graphdem_yade.py on a JSON job written from the
Setup; the script closes YADE's TCP prompt and XML-RPC server before anything else and reports any
listening socket, which fails the run. Supported: 3D spheres, kinematic species (fixed, or moved at
constant velocity by a Motion), initial velocities, Cundall's local damping for settling. Contact
(YADE ViscElMat with Law2_ScGeom_ViscElPhys_Basic): kn = 2 E r1 r2 / (r1 + r2) per contact from
Contact.young, ks = kt_over_kn kn (ViscElMat calls the ratio ``poisson``), damping from the
restitution, Coulomb friction. Not yet: 2D discs, planar walls, rolling resistance and per-species
contact overrides (the 2D scenes run in LAMMPS).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from generators import contact, dem
from generators.record import EngineRun
from generators.yade import runner

CONTACT_MODEL = "linear spring-dashpot, Coulomb friction (YADE ViscElMat, Law2_ScGeom_ViscElPhys_Basic)"
FRAMES = "frames.npz"


def _unsupported(setup: dem.Setup, what: str) -> dem.UnsupportedSetup:
    return dem.UnsupportedSetup(f"{setup.name}: the YADE driver does not run {what} yet; run this scene in LAMMPS")


def _job(setup: dem.Setup) -> dict:
    if setup.dim != 3:
        raise _unsupported(setup, f"{setup.dim}D scenes")
    if setup.walls:
        raise _unsupported(setup, "planar walls")
    if setup.species_contacts:
        raise _unsupported(setup, "per-species contact overrides")
    if setup.contact.rolling_friction:
        raise _unsupported(setup, "rolling resistance")
    c, p = setup.contact, setup.particles
    job = {"young": c.young, "poisson": c.kt_over_kn, "restitution": c.restitution, "density": setup.density,
           "friction": c.friction, "gravity": setup.gravity, "dt": setup.dt, "position": p.x.tolist(),
           "radius": p.radius.tolist(), "fixed": setup.kinematic.tolist()}
    if setup.velocity is not None and np.any(setup.velocity):
        job["velocity"] = np.asarray(setup.velocity, float).tolist()
    return job


def _engine_run(run: EngineRun, setup: dem.Setup, window_seconds: float | None) -> EngineRun:
    """The run with its window timing and step count; refused if YADE kept a listening socket."""
    report = run.notes
    left = report.get("listening_at_start", []) + report.get("listening_sockets", [])
    if left:
        raise runner.YadeError(f"{setup.name}: YADE held listening sockets {left} during the run")
    return dataclasses.replace(run, window_seconds=window_seconds, steps=int(report["iterations"]),
                               notes={"servers_closed": report.get("servers_closed"),
                                      "listening_sockets": report.get("listening_sockets")})


def settle(setup: dem.Setup, workdir: Path) -> tuple[dem.Particles, EngineRun]:
    """Settle with Cundall's local damping until the kinetic energy per moving sphere is below that of a
    nominal sphere at the settling speed, checked every ``check_every`` seconds."""
    s = setup.schedule
    if s.damping_kind != "local":
        raise _unsupported(setup, f"settling damping {s.damping_kind!r} (it damps with Cundall's local damping)")
    mass = contact.sphere_mass(setup.density, setup.nominal_radius)
    job = {"mode": "settle", **_job(setup), "damping": s.damping, "check_every": s.check_every,
           "settle_time": s.max_time, "energy_tol": 0.5 * mass * s.speed**2}
    arrays, run = runner.run(job, Path(workdir), "settle")
    (Path(workdir) / "settle.npz").unlink()
    p = setup.particles
    return dem.Particles(arrays["position"], p.radius, p.species, p.groups), _engine_run(run, setup, None)


def record(setup: dem.Setup, workdir: Path) -> tuple[dem.Frames, EngineRun]:
    """Move each Motion's group at its velocity, run ``start`` steps, then record every ``every`` steps."""
    r = setup.schedule
    motions = [{"mask": setup.group(m.group).tolist(), "velocity": list(m.velocity)} for m in setup.motions]
    job = {"mode": "record", **_job(setup), "motions": motions, "start": r.start, "every": r.every,
           "frames": r.frames}
    workdir = Path(workdir)
    try:
        arrays, run = runner.run(job, workdir, "record")
    except runner.YadeError as exc:   # a failed run, not a numerical blow-up (the trajectory checks name those)
        raise runner.YadeError(f"{setup.name}: {exc}") from exc
    p = setup.particles
    np.savez_compressed(workdir / FRAMES, position=arrays["position"], step=arrays["step"], time=arrays["time"],
                        mass=arrays["mass"], radius=p.radius, species=p.species)
    (workdir / "record.npz").unlink()
    frames = dem.Frames(position=arrays["position"], step=arrays["step"], time=arrays["time"], mass=arrays["mass"],
                        radius=p.radius)
    return frames, _engine_run(run, setup, float(arrays["loop_seconds"]))


def read_raw(raw_dir: Path, dt: float) -> dict:
    """The recorded frames of a run folder (YADE records its own times, so ``dt`` is not needed)."""
    with np.load(Path(raw_dir) / FRAMES) as data:
        return {k: data[k] for k in data.files}
