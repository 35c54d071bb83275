"""graphdem's YADE script, run as ``yade -n -x graphdem_yade.py job.json``.

It imports only yade, numpy and the standard library. Modes (job["mode"]):

- ``settle``: spheres under gravity with Cundall's non-viscous local damping
  (``NewtonIntegrator.damping``) until the kinetic energy per soil sphere is below the tolerance or
  the time limit is reached; writes the final positions.
- ``record``: each motion's spheres move at their constant velocity (fixed spheres not in a motion are
  held), spheres with an initial ``velocity`` start with it; after ``start`` steps the positions of
  every sphere are recorded every ``every`` steps.

``yade`` opens a TCP Python prompt and an XML-RPC server when it starts; the first thing this
script does is close both, and it records any listening socket it still holds in its output.
"""

import gc
import json
import math
import os
import socketserver
import sys
import time

import numpy as np
from yade import O, utils
from yade.wrapper import (
    Bo1_Sphere_Aabb,
    ForceResetter,
    Ig2_Sphere_Sphere_ScGeom,
    InsertionSortCollider,
    InteractionLoop,
    Ip2_ViscElMat_ViscElMat_ViscElPhys,
    Law2_ScGeom_ViscElPhys_Basic,
    NewtonIntegrator,
    ViscElMat,
)


def close_servers():
    """Shut down the socket servers yade started (TCP prompt, XML-RPC info); return how many."""
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


def build(job):
    mat = O.materials.append(ViscElMat(young=job["young"], poisson=job["poisson"], en=job["restitution"],
                                       et=1.0, density=job["density"], frictionAngle=math.atan(job["friction"])))
    ids = []
    for (x, y, z), r, fixed in zip(job["position"], job["radius"], job["fixed"], strict=True):
        ids.append(O.bodies.append(utils.sphere((x, y, z), r, material=mat, fixed=bool(fixed))))
    O.engines = [
        ForceResetter(),
        InsertionSortCollider([Bo1_Sphere_Aabb()]),
        InteractionLoop([Ig2_Sphere_Sphere_ScGeom()], [Ip2_ViscElMat_ViscElMat_ViscElPhys()],
                        [Law2_ScGeom_ViscElPhys_Basic()]),
        NewtonIntegrator(damping=job.get("damping", 0.0), gravity=(0.0, 0.0, -job["gravity"])),
    ]
    O.dt = job["dt"]
    return ids


def positions(ids):
    return np.array([tuple(O.bodies[i].state.pos) for i in ids])


def kinetic_per_sphere(ids, free):
    energy = 0.0
    for i, f in zip(ids, free, strict=True):
        if f:
            s = O.bodies[i].state
            energy += 0.5 * s.mass * s.vel.squaredNorm()
    return energy / max(1, sum(free))


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
    np.savez(out, position=positions(ids), iterations=O.iter, time=O.time, kinetic_per_sphere=energy)


def record(job, out):
    ids = build(job)
    for i, v in zip(ids, job.get("velocity") or [], strict=False):
        if any(v):
            O.bodies[i].state.vel = tuple(v)
    for motion in job["motions"]:
        for i, moving in zip(ids, motion["mask"], strict=True):
            if moving:
                O.bodies[i].state.vel = tuple(motion["velocity"])
    if job["start"]:
        O.run(job["start"], True)
    frames, steps, times = [], [], []
    start = time.perf_counter()
    for f in range(job["frames"]):
        if f:
            O.run(job["every"], True)
        frames.append(positions(ids))
        steps.append(O.iter)
        times.append(O.time)
    loop = time.perf_counter() - start
    np.savez(out, position=np.stack(frames), step=np.array(steps), time=np.array(times),
             mass=np.array([O.bodies[i].state.mass for i in ids]), loop_seconds=loop)


def main():
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
                   "dt": O.dt}, fh)


main()
