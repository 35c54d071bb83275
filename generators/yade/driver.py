"""The YADE driver: runs any scene's Setup (generators/dem.py) that YADE supports.

Debian's ``yade -n -x`` runs generators/yade/scripts/graphdem_yade.py on a JSON job written from the
Setup; the script closes YADE's TCP prompt and XML-RPC server before anything else and reports any
listening socket, which fails the run.

Supported: 3D spheres; 2D discs as spheres of the disc's radius held in the plane (blocked z translation
and x, y rotations) with a disc's mass rho pi r^2 and inertia m r^2 / 2 (unit thickness, the LAMMPS 2D
convention); kinematic species (fixed, or moved at constant velocity by a Motion, from step 0 or from the
first recorded frame; two kinematic spheres never interact); a load Platen (one clump, free along its
axis only, pushed by a permanent force; contact forces of force groups averaged over force_samples steps
of each frame interval); planar walls
(``utils.wall``); initial velocities; per-species overrides that lower the friction (and keep or zero
the rolling friction); a perturbation after a recorded frame (a DEM ensemble member); settling with
Cundall's local damping or a viscous drag.

Contact (YADE ViscElMat with Law2_ScGeom_ViscElPhys_Basic), matched to the LAMMPS driver's linear
spring-dashpot: each sphere has its own material with young = kn / r, so two spheres meet with the
constant normal stiffness Contact.kn whatever their radii (YADE: kn = series of 2 young_i r); ks =
kt_over_kn kn (ViscElMat's ``poisson``); the dashpot from the restitution; Coulomb friction; rolling
resistance as a constant torque mur R_eff |Fn| against the relative rotation (``mR`` = mur r / 2 per
sphere, combined by YADE's harmonic mean into mur R_eff; LAMMPS' ``rolling sds`` reaches the same
limit torque through a spring). A wall meets a sphere of radius r with kn 2 r / (r + r_nominal) times
Contact.kn (Contact.kn at the nominal radius).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from generators import contact, dem
from generators.record import EngineRun
from generators.yade import runner

CONTACT_MODEL = "linear spring-dashpot, Coulomb friction (YADE ViscElMat, Law2_ScGeom_ViscElPhys_Basic)"
FRAMES = "frames.npz"
PARALLEL = "threads"        # more cores: YADE's own threads (-j) in one process (generators/engines.py)
ERRORS = (runner.YadeError,)


def _unsupported(setup: dem.Setup, what: str) -> dem.UnsupportedSetup:
    return dem.UnsupportedSetup(f"{setup.name}: the YADE driver does not run {what} yet; run this scene in LAMMPS")


def _one_process(setup: dem.Setup, ranks: int) -> None:
    if ranks != 1:
        raise dem.UnsupportedSetup(f"{setup.name}: ranks = {ranks}; YADE runs one process (ranks = 1): MPI ranks "
                                   "are a LAMMPS setting")


def _species_contacts(setup: dem.Setup) -> dict[str, list[float]]:
    """Per-species overrides as (friction, rolling friction). YADE gives a contact the smaller of its two
    bodies' friction angles and the harmonic mean of their rolling coefficients: that is LAMMPS'
    `pair_coeff * s` for an override that lowers the friction and keeps or zeroes the rolling friction,
    and changes nothing else."""
    out = {}
    base = setup.contact
    for species, c in setup.species_contacts.items():
        same_rest = dataclasses.replace(c, friction=base.friction, rolling_friction=base.rolling_friction) == base
        if not same_rest or c.friction > base.friction or c.rolling_friction not in (0.0, base.rolling_friction):
            raise _unsupported(setup, f"the per-species contact of species {species} ({c}): it runs overrides that "
                                      "lower the friction and keep or zero the rolling friction only")
        out[str(species)] = [c.friction, c.rolling_friction]
    return out


def _job(setup: dem.Setup) -> dict:
    if setup.dim not in (2, 3):
        raise _unsupported(setup, f"{setup.dim}D scenes")
    c, p = setup.contact, setup.particles
    walls = []
    for w in setup.walls:
        walls += [[w.axis, float(w.lower), 1]] if w.lower is not None else []
        walls += [[w.axis, float(w.upper), -1]] if w.upper is not None else []
    job = {"dim": setup.dim, "kn": c.kn, "kt_over_kn": c.kt_over_kn, "restitution": c.restitution,
           "density": setup.density, "friction": c.friction, "rolling_friction": c.rolling_friction,
           "species_contacts": _species_contacts(setup), "gravity": setup.gravity, "tilt": setup.tilt,
           "dt": setup.dt, "nominal_radius": setup.nominal_radius, "position": p.x.tolist(),
           "radius": p.radius.tolist(), "species": p.species.tolist(), "fixed": setup.kinematic.tolist(),
           "walls": walls}
    if setup.velocity is not None and np.any(setup.velocity):
        job["velocity"] = np.asarray(setup.velocity, float).tolist()
    return job


def _engine_run(run: EngineRun, setup: dem.Setup, window_seconds: float | None,
                runup_seconds: float | None = None) -> EngineRun:
    """The run with its window timing and step count; refused if YADE kept a listening socket."""
    report = run.notes
    left = report.get("listening_at_start", []) + report.get("listening_sockets", [])
    if left:
        raise runner.YadeError(f"{setup.name}: YADE held listening sockets {left} during the run")
    return dataclasses.replace(run, window_seconds=window_seconds, runup_seconds=runup_seconds,
                               steps=int(report["iterations"]),
                               notes={"servers_closed": report.get("servers_closed"),
                                      "listening_sockets": report.get("listening_sockets")})


def settle(setup: dem.Setup, workdir: Path, ranks: int = 1, threads: int = 1) -> tuple[dem.Particles, EngineRun]:
    """Settle with Cundall's local damping or a viscous drag until the kinetic energy per moving sphere is
    below that of a nominal sphere at the settling speed, checked every ``check_every`` seconds (one process:
    ``ranks`` must be 1)."""
    _one_process(setup, ranks)
    s = setup.schedule
    mass = contact.particle_mass(setup.density, setup.nominal_radius, setup.dim)
    if s.damping_kind == "local":
        damping = {"damping": s.damping}
    elif s.damping_kind == "viscous":       # -damping m_nominal v on a nominal sphere, as LAMMPS' fix viscous
        damping = {"drag": s.damping * mass / (6.0 * math.pi * setup.nominal_radius)}
    else:
        raise _unsupported(setup, f"settling damping {s.damping_kind!r} (it damps with 'local' or 'viscous')")
    job = {"mode": "settle", **_job(setup), **damping, "check_every": s.check_every,
           "settle_time": s.max_time, "energy_tol": 0.5 * mass * s.speed**2}
    arrays, run = runner.run(job, Path(workdir), "settle", threads=threads)
    (Path(workdir) / "settle.npz").unlink()
    p = setup.particles
    return dem.Particles(arrays["position"], p.radius, p.species, p.groups), _engine_run(run, setup, None)


def _force_samples(setup: dem.Setup) -> int:
    if setup.schedule.every % setup.force_samples:
        raise _unsupported(setup, f"{setup.force_samples} force samples in a frame interval of {setup.schedule.every} "
                                  "steps (not a divisor)")
    return int(setup.force_samples)


def run_recording(setup: dem.Setup, workdir: Path, ranks: int = 1, threads: int = 1) -> tuple[dem.Frames, EngineRun]:
    """Move each Motion's group at its velocity, run ``start`` steps, then record every ``every`` steps, displacing
    the particles by the Setup's Perturbation right after its frame (one process: ``ranks`` must be 1; ``threads``
    OpenMP threads, YADE's ``-j``)."""
    _one_process(setup, ranks)
    r = setup.schedule
    motions = [{"mask": setup.group(m.group).tolist(), "velocity": list(m.velocity), "from_record": m.from_record}
               for m in setup.motions]
    job = {"mode": "record", **_job(setup), "motions": motions, "start": r.start, "every": r.every,
           "frames": r.frames, "force_groups": {name: setup.group(name).tolist() for name in setup.force_groups},
           "force_samples": _force_samples(setup)}
    perturbation = dem.checked_perturbation(setup)
    if perturbation is not None:
        job["perturbation"] = {"frame": perturbation.frame,
                               "displacement": np.asarray(perturbation.displacement, float).tolist()}
    if setup.platen is not None:
        pl = setup.platen
        if setup.dim != 3 or not np.all(setup.kinematic[setup.group(pl.group)]):
            raise _unsupported(setup, "a platen outside 3D or of particles not of a kinematic species")
        job["platen"] = {"mask": setup.group(pl.group).tolist(), "mass": pl.mass, "force": pl.force, "axis": pl.axis,
                         "ramp": pl.ramp}
    workdir = Path(workdir)
    try:
        arrays, run = runner.run(job, workdir, "record", threads=threads)
    except runner.YadeError as exc:   # a failed run, not a numerical blow-up (the trajectory checks name those)
        raise runner.YadeError(f"{setup.name}: {exc}") from exc
    p = setup.particles
    np.savez_compressed(workdir / FRAMES, position=arrays["position"], step=arrays["step"], time=arrays["time"],
                        mass=arrays["mass"], radius=p.radius, species=p.species)
    (workdir / "record.npz").unlink()
    frames = dem.Frames(position=arrays["position"], step=arrays["step"], time=arrays["time"], mass=arrays["mass"],
                        radius=p.radius, kinetic_energy=arrays["kinetic_energy"],
                        kinematic_force=arrays["kinematic_force"],
                        group_force={name: arrays[f"group_force:{name}"] for name in setup.force_groups})
    return frames, _engine_run(run, setup, float(arrays["loop_seconds"]), float(arrays["runup_seconds"]))


def read_raw(raw_dir: Path, dt: float) -> dict:
    """The recorded frames of a run folder (YADE records its own times, so ``dt`` is not needed)."""
    with np.load(Path(raw_dir) / FRAMES) as data:
        return {k: data[k] for k in data.files}
