"""graphdem's YADE script, run as ``yade -n -x graphdem_yade.py job.json``.

It imports only yade, numpy and the standard library. Modes (job["mode"]):

- ``settle``: spheres under gravity with Cundall's non-viscous local damping
  (``NewtonIntegrator.damping``) or a viscous drag (``LinearDragEngine``) until the kinetic energy per
  moving sphere is below the tolerance or the time limit is reached; writes the final positions.
- ``record``: each motion's spheres move at their constant velocity (fixed spheres not in a motion are
  held; a motion ``from_record`` starts at the first recorded frame), spheres with an initial
  ``velocity`` start with it; a ``platen`` (its spheres one clump of the given mass, free along one
  axis only, pushed by a permanent force that ramps up in a staircase of 100 steps over ``ramp``
  DEM steps) is loaded; after ``start`` steps the positions of every sphere are recorded every
  ``every`` steps, with the moving spheres' kinetic energy, the total contact force on the fixed ones
  and the contact force on each of the ``force_groups`` (averaged over ``force_samples`` equally spaced
  steps of the frame interval, the last at the frame; frame 0's over the run-up's last interval); with a
  ``perturbation``, every sphere is displaced by its row of the displacement right after frame ``frame`` is
  recorded (a DEM ensemble member).

graphdem starts YADE's launcher without its TCP Python prompt and XML-RPC server (generators/yade/runner.py).
As a second guard the script shuts down any socket server it finds at its start (counted in its output: 0)
and records every listening socket the process holds, which the driver refuses.
"""

import gc
import json
import math
import os
import shutil
import socketserver
import sys
import time

import numpy as np
from yade import O, utils
from yade.wrapper import (
    Bo1_Sphere_Aabb,
    Bo1_Wall_Aabb,
    ForceResetter,
    Ig2_Sphere_Sphere_ScGeom,
    Ig2_Wall_Sphere_ScGeom,
    InsertionSortCollider,
    InteractionLoop,
    Ip2_ViscElMat_ViscElMat_ViscElPhys,
    Law2_ScGeom_ViscElPhys_Basic,
    LinearDragEngine,
    NewtonIntegrator,
    PyRunner,
    ViscElMat,
)


def close_servers():
    """Shut down any socket server in this process (YADE's TCP prompt, XML-RPC info); return how many (graphdem
    starts YADE without them, so 0)."""
    closed = 0
    for obj in gc.get_objects():
        if isinstance(obj, socketserver.BaseServer):
            obj.shutdown()
            obj.server_close()
            closed += 1
    return closed


def listening_sockets():
    """TCP sockets in LISTEN state that this process holds (from /proc)."""
    inodes = set()
    for fd in os.listdir("/proc/self/fd"):
        try:
            target = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            lines = open(table).read().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            words = line.split()
            if words[3] == "0A" and words[9] in inodes:      # 0A: LISTEN
                found.append(words[1])
    return found


def material(job, young, friction, rolling):
    """A ViscElMat of the job's contact: YADE combines two bodies' stiffnesses in series
    (kn = kn1 kn2 / (kn1 + kn2) with kn_i = 2 young_i r), friction angles by their minimum and rolling
    coefficients mR by their harmonic mean."""
    return O.materials.append(ViscElMat(young=young, poisson=job["kt_over_kn"], en=job["restitution"], et=1.0,
                                        density=job["density"], frictionAngle=math.atan(friction),
                                        mR=rolling, mRtype=1))


def gravity_vector(job):
    """Gravity along -y (2D) or -z (3D), tilted by ``tilt`` radians towards +x."""
    g, tilt = job["gravity"], job.get("tilt", 0.0)
    if job["dim"] == 2:
        return (g * math.sin(tilt), -g * math.cos(tilt), 0.0)
    return (g * math.sin(tilt), 0.0, -g * math.cos(tilt))


# Collision masks: two kinematic spheres never interact (the collider's avoidSelfInteractionMask drops pairs
# of the same mask that has its bit), as LAMMPS excludes kinematic type pairs; moving spheres meet everything.
MOVING_MASK, KINEMATIC_MASK, SELF_AVOID = 0b001, 0b011, 0b010


def build(job):
    """Bodies, walls and engines of the job. Each sphere has its own material with young = kn / r, so
    that two spheres meet with the job's constant kn whatever their radii; 2D discs are spheres held in
    the plane (no z translation, no x or y rotation) with the mass and inertia of a disc of unit
    thickness."""
    kn, dim = job["kn"], job["dim"]
    overrides = {int(k): v for k, v in job.get("species_contacts", {}).items()}
    platen = job.get("platen")
    in_platen = platen["mask"] if platen else [False] * len(job["radius"])
    ids = []
    for pos, r, fixed, species, clumped in zip(job["position"], job["radius"], job["fixed"], job["species"], in_platen,
                                               strict=True):
        friction, rolling = overrides.get(int(species), (job["friction"], job["rolling_friction"]))
        mat = material(job, kn / r, friction, 0.5 * rolling * r)
        body = utils.sphere(vector3(pos), r, material=mat, fixed=bool(fixed) and not clumped,
                            mask=KINEMATIC_MASK if fixed else MOVING_MASK)
        if dim == 2:
            mass = job["density"] * math.pi * r * r
            body.state.mass = mass
            body.state.inertia = (0.5 * mass * r * r,) * 3
            if not fixed:
                body.state.blockedDOFs = "zXY"
        ids.append(O.bodies.append(body))
    # a wall meets sphere i with kn = series(2 kn, 2 young_w r_i): young_w = kn / r_nominal gives kn at the
    # nominal radius; its mR is large so that the harmonic mean gives the sphere's mur * r_i
    wall_mat = material(job, kn / job["nominal_radius"], job["friction"], 1.0e6 if job["rolling_friction"] else 0.0)
    for axis, value, sense in job.get("walls", []):
        centre = [0.0, 0.0, 0.0]
        centre[axis] = value
        O.bodies.append(utils.wall(tuple(centre), axis=axis, sense=sense, material=wall_mat))
    if platen:
        platen["clump"] = make_platen(platen, ids)
    free = [i for i, f in zip(ids, job["fixed"], strict=True) if not f]
    engines = [
        ForceResetter(),
        InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Wall_Aabb()], avoidSelfInteractionMask=SELF_AVOID),
        InteractionLoop([Ig2_Sphere_Sphere_ScGeom(), Ig2_Wall_Sphere_ScGeom()], [Ip2_ViscElMat_ViscElMat_ViscElPhys()],
                        [Law2_ScGeom_ViscElPhys_Basic()]),
    ]
    if job.get("drag"):                    # viscous settling damping: F = -6 pi nu r v on each moving sphere
        engines.append(LinearDragEngine(nu=job["drag"], ids=free))
    engines.append(NewtonIntegrator(damping=job.get("damping", 0.0), gravity=gravity_vector(job)))
    O.engines = engines
    O.dt = job["dt"]
    return ids


def make_platen(platen, ids):
    """The platen's spheres as one clump of the platen's mass, free along its axis only (the rotations
    are blocked); returns the clump's id. Gravity acts on the clump's mass (NewtonIntegrator)."""
    clump = O.bodies.clump([i for i, m in zip(ids, platen["mask"], strict=True) if m])
    state = O.bodies[clump].state
    state.mass = platen["mass"]
    for i in O.bodies[clump].shape.members:          # each sphere M / N, as LAMMPS gives each platen atom
        O.bodies[i].state.mass = platen["mass"] / len(O.bodies[clump].shape.members)
    state.blockedDOFs = "".join(a for k, a in enumerate("xyz") if k != platen["axis"]) + "XYZ"
    state.vel = (0.0, 0.0, 0.0)
    return clump


def load_platen(platen, fraction):
    """The platen's permanent external force at ``fraction`` of its full value."""
    force = [0.0, 0.0, 0.0]
    force[platen["axis"]] = fraction * platen["force"]
    O.forces.setPermF(platen["clump"], tuple(force))


def periodic(name, function, period):
    """A PyRunner calling ``function`` every ``period`` steps: PyRunner runs its command in ``__main__``, so the
    function is put there under ``name``. (Stopping a run for it would cost YADE's O.run wait, ~40 ms a call.)"""
    import __main__
    setattr(__main__, name, function)
    O.engines = O.engines + [PyRunner(command=f"{name}()", iterPeriod=max(1, int(period)))]


def ramp_platen(job):
    """A platen's force ramping up linearly over its first ``ramp`` steps, updated every ramp / 100 steps (a
    staircase of 100 steps), full from then on."""
    platen = job["platen"]
    ramp = int(platen.get("ramp", 0))
    if ramp <= 0:
        load_platen(platen, 1.0)
        return
    load_platen(platen, 0.0)
    periodic("graphdem_ramp", lambda: load_platen(platen, min(1.0, O.iter / ramp)), max(1, ramp // 100))


def vector3(v):
    """A 2D or 3D vector as YADE's 3-vector (2D: z = 0)."""
    return (*v, 0.0) if len(v) == 2 else tuple(v)


def positions(ids, dim):
    return np.array([tuple(O.bodies[i].state.pos)[:dim] for i in ids])


def kinetic_per_sphere(ids, free):
    energy = 0.0
    for i, f in zip(ids, free, strict=True):
        if f:
            s = O.bodies[i].state
            energy += 0.5 * s.mass * s.vel.squaredNorm()
    return energy / max(1, sum(free))


def kinetic_energy(ids, free):
    """Translational plus rotational kinetic energy of the moving spheres."""
    energy = 0.0
    for i, f in zip(ids, free, strict=True):
        if f:
            s = O.bodies[i].state
            w = s.angVel
            energy += 0.5 * s.mass * s.vel.squaredNorm() + 0.5 * sum(s.inertia[k] * w[k] ** 2 for k in range(3))
    return energy


def force_on(ids, fixed, dim):
    """Total contact force on the fixed (kinematic) spheres."""
    total = np.zeros(3)
    for i, f in zip(ids, fixed, strict=True):
        if f:
            total += np.array(tuple(O.forces.f(i)))
    return total[:dim]


def perturb(ids, displacement):
    """Displace each sphere by its row of ``displacement`` (a DEM ensemble member, after a recorded frame): the
    positions change, the velocities, rotations and contacts go on as they were."""
    for i, d in zip(ids, displacement, strict=True):
        if any(d):
            state = O.bodies[i].state
            state.pos = tuple(x + dx for x, dx in zip(tuple(state.pos), vector3(d), strict=True))


def settle(job, out):
    ids = build(job)
    free = [not f for f in job["fixed"]]
    chunk = max(1, int(round(job["check_every"] / O.dt)))
    n_chunks = max(1, int(math.ceil(job["settle_time"] / (chunk * O.dt))))
    energy = float("nan")
    for _ in range(n_chunks):
        O.run(chunk, True)                      # O.run returns at once: wait=True blocks until done
        energy = kinetic_per_sphere(ids, free)
        if energy < job["energy_tol"]:
            break
    np.savez(out, position=positions(ids, job["dim"]), iterations=O.iter, time=O.time, kinetic_per_sphere=energy)


def record(job, out):
    ids = build(job)
    for i, v in zip(ids, job.get("velocity") or [], strict=False):
        if any(v):
            O.bodies[i].state.vel = vector3(v)
    def move(motions):
        for motion in motions:
            for i, moving in zip(ids, motion["mask"], strict=True):
                if moving:
                    O.bodies[i].state.vel = vector3(motion["velocity"])

    move([m for m in job["motions"] if not m.get("from_record")])
    groups = {name: [i for i, m in zip(ids, mask, strict=True) if m]
              for name, mask in job.get("force_groups", {}).items()}
    samples, every = int(job.get("force_samples", 1)), job["every"]

    def group_force():
        return {name: sum((np.array(tuple(O.forces.f(i))) for i in members), np.zeros(3))[:job["dim"]]
                for name, members in groups.items()}

    taken = []                     # (O.iter, group forces) every every / samples steps

    def window():
        """The group forces averaged over the samples of the frame interval ending now."""
        now = [f for it, f in taken if O.iter - every < it <= O.iter]
        if not now:
            return group_force()
        return {name: sum(f[name] for f in now) / len(now) for name in groups}

    if groups and samples > 1:
        # PyRunner runs inside step O.iter + 1 (O.iter counts the steps done before it)
        periodic("graphdem_sample", lambda: taken.append((O.iter + 1, group_force())), every // samples)
    if job.get("platen"):
        ramp_platen(job)
    runup = time.perf_counter()
    if job["start"]:
        O.run(job["start"], True)
    first = window()
    move([m for m in job["motions"] if m.get("from_record")])
    runup = time.perf_counter() - runup
    free = [not f for f in job["fixed"]]
    group_forces = {name: [] for name in groups}
    frames, steps, times, energies, forces = [], [], [], [], []
    loop = 0.0
    for f in range(job["frames"]):
        now = first
        if f:
            start = time.perf_counter()
            O.run(every, True)
            loop += time.perf_counter() - start
            now = window()
            taken = [t for t in taken if t[0] > O.iter - every]
        frames.append(positions(ids, job["dim"]))
        steps.append(O.iter)
        times.append(O.time)
        energies.append(kinetic_energy(ids, free))
        forces.append(force_on(ids, job["fixed"], job["dim"]))
        for name, value in now.items():
            group_forces[name].append(value)
        if job.get("perturbation") and f == job["perturbation"]["frame"]:
            perturb(ids, job["perturbation"]["displacement"])
    np.savez(out, position=np.stack(frames), step=np.array(steps), time=np.array(times),
             **{f"group_force:{name}": np.stack(v) for name, v in group_forces.items()},
             mass=np.array([O.bodies[i].state.mass for i in ids]), kinetic_energy=np.array(energies),
             kinematic_force=np.stack(forces), loop_seconds=loop,
             runup_seconds=runup)


def yade_temp_dir():
    """The directory YADE made for this process (``/tmp/yade-XXXXXX``, from ``O.tmpFilename()``)."""
    return os.path.dirname(O.tmpFilename())


def remove_yade_temp_dir(path):
    """Remove YADE's per-process temporary directory. YADE deletes it only on the interactive session's
    exit, which ``-x`` never reaches, so every batch run would leave an empty ``/tmp/yade-XXXXXX`` behind.
    Only a directory named ``yade-*`` is touched."""
    if os.path.basename(path).startswith("yade-") and os.path.isdir(path):
        shutil.rmtree(path, ignore_errors=True)


def main():
    temp_dir = yade_temp_dir()
    print(f"graphdem: YADE's temporary directory {temp_dir} (removed at the end)", flush=True)
    try:
        closed = close_servers()
        listening_at_start = listening_sockets()
        with open(sys.argv[1]) as fh:
            job = json.load(fh)
        out = job["out"]
        {"settle": settle, "record": record}[job["mode"]](job, out + ".tmp.npz")
        os.replace(out + ".tmp.npz", out)
        with open(out + ".json", "w") as fh:
            json.dump({"servers_closed": closed, "listening_at_start": listening_at_start,
                       "listening_sockets": listening_sockets(),
                       "iterations": O.iter,
                       "dt": O.dt,
                       "yade_temp_dir": temp_dir}, fh)
    finally:
        remove_yade_temp_dir(temp_dir)


main()
